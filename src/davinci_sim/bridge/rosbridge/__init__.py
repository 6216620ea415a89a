"""A generic rosbridge v2 server: websockets, sessions, the topic/service/action graph,
message definitions of both ROS dialects and their validation. It knows nothing of the dVRK
or the simulator; nodes (``davinci_sim.bridge.dvrk_node`` …) attach to it."""
