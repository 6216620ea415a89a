"""``sensor_msgs`` for davinci-sim scripts when ROS's is not installed (see ``msg``)."""
