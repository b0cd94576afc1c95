"""QoS profiles of the catheter node graph (DESIGN section 4); the names are in
`catheter_common.topics`."""
from rclpy.qos import (QoSDurabilityPolicy, QoSHistoryPolicy, QoSProfile,
                       QoSReliabilityPolicy, qos_profile_sensor_data)

#: camera frames, control points, tip wrench: best effort, keep last 5, volatile
QOS_SENSOR = qos_profile_sensor_data
#: 1 kHz streams: best effort, depth 1 (latest wins, never queue stale data)
QOS_FAST = QoSProfile(history=QoSHistoryPolicy.KEEP_LAST, depth=1,
                      reliability=QoSReliabilityPolicy.BEST_EFFORT,
                      durability=QoSDurabilityPolicy.VOLATILE)
#: on-demand topics (tip load, shape, diagnostics): reliable, keep last 10
QOS_DEFAULT = QoSProfile(history=QoSHistoryPolicy.KEEP_LAST, depth=10,
                         reliability=QoSReliabilityPolicy.RELIABLE,
                         durability=QoSDurabilityPolicy.VOLATILE)
