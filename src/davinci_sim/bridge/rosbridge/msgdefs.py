"""ROS message, service and action definitions as data, in the ``.msg`` text syntax.

These are the interfaces the bridge speaks (rosbridge.md §3, dvrk.md §2): std_msgs,
geometry_msgs, sensor_msgs, crtk_msgs, std_srvs, tf2_msgs, diagnostic_msgs, the logging
types behind ``/rosout``, the rosapi services and two example interfaces that roslibpy's own
tests use. Each entry is written from the public interface definition; the syntax is the
ROS one (``type name``, ``type[] name``, ``type[N] name``, ``TYPE NAME=value`` constants,
``type name default`` ROS 2 defaults) plus one extension: a line ending in ``# ros1`` or
``# ros2`` exists only in that dialect (``Header.seq``, ``CameraInfo.D`` vs ``d`` …).

Names are canonical ``pkg/Type``; :mod:`davinci_sim.bridge.rosbridge.types` resolves both spellings.
"""

from __future__ import annotations

from typing import Final

MESSAGES: Final[dict[str, str]] = {
    # ------------------------------------------------------------------ std_msgs
    "std_msgs/Header": "uint32 seq  # ros1\ntime stamp\nstring frame_id",
    "std_msgs/String": "string data",
    "std_msgs/Bool": "bool data",
    "std_msgs/Empty": "",
    "std_msgs/Float64": "float64 data",
    "std_msgs/Float32": "float32 data",
    "std_msgs/Int32": "int32 data",
    "std_msgs/Int64": "int64 data",
    "std_msgs/UInt8": "uint8 data",
    "std_msgs/ColorRGBA": "float32 r\nfloat32 g\nfloat32 b\nfloat32 a",
    "std_msgs/MultiArrayDimension": "string label\nuint32 size\nuint32 stride",
    "std_msgs/MultiArrayLayout": "MultiArrayDimension[] dim\nuint32 data_offset",
    "std_msgs/Float64MultiArray": "MultiArrayLayout layout\nfloat64[] data",
    "std_msgs/Int32MultiArray": "MultiArrayLayout layout\nint32[] data",
    # ------------------------------------------------------------------ geometry_msgs
    "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Point": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Quaternion": "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1",
    "geometry_msgs/Pose": "Point position\nQuaternion orientation",
    "geometry_msgs/PoseStamped": "std_msgs/Header header\nPose pose",
    "geometry_msgs/PoseArray": "std_msgs/Header header\nPose[] poses",
    "geometry_msgs/Transform": "Vector3 translation\nQuaternion rotation",
    "geometry_msgs/TransformStamped": (
        "std_msgs/Header header\nstring child_frame_id\nTransform transform"
    ),
    "geometry_msgs/Twist": "Vector3 linear\nVector3 angular",
    "geometry_msgs/TwistStamped": "std_msgs/Header header\nTwist twist",
    "geometry_msgs/Wrench": "Vector3 force\nVector3 torque",
    "geometry_msgs/WrenchStamped": "std_msgs/Header header\nWrench wrench",
    "geometry_msgs/PointStamped": "std_msgs/Header header\nPoint point",
    "geometry_msgs/Vector3Stamped": "std_msgs/Header header\nVector3 vector",
    "geometry_msgs/QuaternionStamped": "std_msgs/Header header\nQuaternion quaternion",
    # ------------------------------------------------------------------ sensor_msgs
    "sensor_msgs/JointState": (
        "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\n"
        "float64[] effort"
    ),
    "sensor_msgs/Joy": "std_msgs/Header header\nfloat32[] axes\nint32[] buttons",
    "sensor_msgs/Image": (
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n"
        "uint8 is_bigendian\nuint32 step\nuint8[] data"
    ),
    "sensor_msgs/CompressedImage": "std_msgs/Header header\nstring format\nuint8[] data",
    "sensor_msgs/RegionOfInterest": (
        "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify"
    ),
    "sensor_msgs/CameraInfo": (
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n"
        "float64[] D  # ros1\nfloat64[9] K  # ros1\nfloat64[9] R  # ros1\nfloat64[12] P  # ros1\n"
        "float64[] d  # ros2\nfloat64[9] k  # ros2\nfloat64[9] r  # ros2\nfloat64[12] p  # ros2\n"
        "uint32 binning_x\nuint32 binning_y\nRegionOfInterest roi"
    ),
    # ------------------------------------------------------------------ crtk_msgs (dvrk.md 2.2)
    "crtk_msgs/OperatingState": (
        "std_msgs/Header header\nstring state\nbool is_homed\nbool is_busy"
    ),
    "crtk_msgs/StringStamped": "std_msgs/Header header\nstring string",
    "crtk_msgs/CartesianState": (
        "std_msgs/Header header\ngeometry_msgs/Pose pose\nstd_msgs/Bool pose_is_valid\n"
        "geometry_msgs/Twist twist\nstd_msgs/Bool twist_is_valid\n"
        "geometry_msgs/Wrench wrench\nstd_msgs/Bool wrench_is_valid"
    ),
    # servo_ci's goal (dvrk_mtm_cartesian_impedance.py): a virtual fixture at force_position /
    # force_orientation, gains on each side of it
    "crtk_msgs/CartesianImpedanceHalfPlaneGains": (
        "geometry_msgs/Vector3 p\ngeometry_msgs/Vector3 d\ngeometry_msgs/Vector3 bias\n"
        "geometry_msgs/Vector3 deadband"
    ),
    "crtk_msgs/CartesianImpedance": (
        "std_msgs/Header header\ngeometry_msgs/Quaternion force_orientation\n"
        "geometry_msgs/Vector3 force_position\ngeometry_msgs/Quaternion torque_orientation\n"
        "crtk_msgs/CartesianImpedanceHalfPlaneGains position_positive\n"
        "crtk_msgs/CartesianImpedanceHalfPlaneGains position_negative\n"
        "crtk_msgs/CartesianImpedanceHalfPlaneGains orientation_positive\n"
        "crtk_msgs/CartesianImpedanceHalfPlaneGains orientation_negative"
    ),
    # ------------------------------------------------------------------ tf, diagnostics, logs
    "tf2_msgs/TFMessage": "geometry_msgs/TransformStamped[] transforms",
    "diagnostic_msgs/KeyValue": "string key\nstring value",
    "diagnostic_msgs/DiagnosticStatus": (
        "byte OK=0\nbyte WARN=1\nbyte ERROR=2\nbyte STALE=3\n"
        "byte level\nstring name\nstring message\nstring hardware_id\nKeyValue[] values"
    ),
    "diagnostic_msgs/DiagnosticArray": "std_msgs/Header header\nDiagnosticStatus[] status",
    "rosgraph_msgs/Log": (
        "byte DEBUG=1\nbyte INFO=2\nbyte WARN=4\nbyte ERROR=8\nbyte FATAL=16\n"
        "std_msgs/Header header\nbyte level\nstring name\nstring msg\nstring file\n"
        "string function\nuint32 line\nstring[] topics"
    ),
    "rcl_interfaces/Log": (
        "uint8 DEBUG=10\nuint8 INFO=20\nuint8 WARN=30\nuint8 ERROR=40\nuint8 FATAL=50\n"
        "time stamp\nuint8 level\nstring name\nstring msg\nstring file\nstring function\n"
        "uint32 line"
    ),
    "rosgraph_msgs/Clock": "time clock",
    # ------------------------------------------------------------------ rosapi (rosbridge.md 2.2)
    "rosapi/TypeDef": (
        "string type\nstring[] fieldnames\nstring[] fieldtypes\nint32[] fieldarraylen\n"
        "string[] examples\nstring[] constnames\nstring[] constvalues"
    ),
}

SERVICES: Final[dict[str, str]] = {
    "std_srvs/Empty": "---",
    "std_srvs/Trigger": "---\nbool success\nstring message",
    "std_srvs/SetBool": "bool data\n---\nbool success\nstring message",
    # crtk_msgs (dvrk.md 2.2): the number of joints given to forward_kinematics selects the frame.
    "crtk_msgs/QueryForwardKinematics": (
        "float64[] jp\ngeometry_msgs/Pose cp\n---\ngeometry_msgs/Pose cp\nbool result\n"
        "string message"
    ),
    "crtk_msgs/QueryInverseKinematics": (
        "geometry_msgs/Pose cp\nfloat64[] jp\n---\nfloat64[] jp\nbool result\nstring message"
    ),
    "crtk_msgs/TriggerOperatingState": "---\ncrtk_msgs/OperatingState operating_state",
    "example_interfaces/AddTwoInts": "int64 a\nint64 b\n---\nint64 sum",
    # rosapi (rosbridge.md 2.2); ROS 1 names the get_param default ``default``.
    "rosapi/Topics": "---\nstring[] topics\nstring[] types",
    "rosapi/TopicsForType": "string type\n---\nstring[] topics",
    "rosapi/TopicType": "string topic\n---\nstring type",
    "rosapi/Services": "---\nstring[] services",
    "rosapi/ServicesForType": "string type\n---\nstring[] services",
    "rosapi/ServiceType": "string service\n---\nstring type",
    "rosapi/ServiceProviders": "string service\n---\nstring[] providers",
    "rosapi/ServiceNode": "string service\n---\nstring node",
    "rosapi/Publishers": "string topic\n---\nstring[] publishers",
    "rosapi/Subscribers": "string topic\n---\nstring[] subscribers",
    "rosapi/Nodes": "---\nstring[] nodes",
    "rosapi/NodeDetails": (
        "string node\n---\nstring[] subscribing\nstring[] publishing\nstring[] services"
    ),
    "rosapi/GetActionServers": "---\nstring[] action_servers",
    "rosapi/GetTime": "---\ntime time",
    "rosapi/GetROSVersion": "---\nuint8 version\nstring distro",
    "rosapi/GetParam": (
        "string name\nstring default  # ros1\nstring default_value  # ros2\n---\nstring value"
    ),
    "rosapi/SetParam": "string name\nstring value\n---",
    "rosapi/DeleteParam": "string name\n---",
    "rosapi/HasParam": "string name\n---\nbool exists",
    "rosapi/GetParamNames": "---\nstring[] names",
    "rosapi/MessageDetails": "string type\n---\nTypeDef[] typedefs",
    "rosapi/ServiceRequestDetails": "string type\n---\nTypeDef[] typedefs",
    "rosapi/ServiceResponseDetails": "string type\n---\nTypeDef[] typedefs",
}

ACTIONS: Final[dict[str, str]] = {
    "example_interfaces/Fibonacci": "int32 order\n---\nint32[] sequence\n---\nint32[] sequence",
}

#: Packages whose ROS 2 name differs (``rosapi`` services live in ``rosapi_msgs`` in ROS 2,
#: the ``/rosout`` type is ``rcl_interfaces/msg/Log``).
ROS2_PACKAGE_ALIASES: Final[dict[str, str]] = {"rosapi_msgs": "rosapi"}
