"""QoS profiles of the catheter node graph (DESIGN section 4); the names are in
`catheter_common.topics`."""
from rclpy.qos import (QoSDurabilityPolicy, QoSHistoryPolicy, QoSProfile,
                       QoSReliabilityPolicy, qos_profile_sensor_data)

#: camera frames, control points, tip wrench: best effort, keep last 5, volatile
QOS_SENSOR = qos_profile_sensor_data
#: 1 kHz streams: best effort (a late sample is never re-sent), keep last 10: a subscriber
#: whose process was preempted for a few periods still takes every sample (with depth 1 the
#: split layout lost 0.7-0.9 % of the link samples over DDS beyond the injected loss, measured
#: by scripts/bench system); every consumer keeps only the newest state, so a short burst
#: costs one callback each and queues nothing stale beyond 10 ms
QOS_FAST = QoSProfile(history=QoSHistoryPolicy.KEEP_LAST, depth=10,
                      reliability=QoSReliabilityPolicy.BEST_EFFORT,
                      durability=QoSDurabilityPolicy.VOLATILE)
#: the link topics between the master and the slave (two machines in a deployment: the slave's
#: /slave/force and /slave/impedance taken at the master, the master's /master/command taken at
#: the slave): QOS_FAST's profile with a deeper receive queue, keep last 1000 (1 s at 1 kHz).
#: The link must not lose what it was sent: with depth 10 a master process stalled 11.7 ms
#: lost one /slave/force sample (DDS reporting none lost: the reader's own queue overflowed;
#: scripts/bench system, split layout, 2026-12-03), and with depth 100 the benchmark
#: machine's host held the master's CPU ~117 ms and two were lost the same way (the same
#: day, later: its stall probe saw 100 ms stalls every few seconds in slow phases). A burst
#: after a stall costs one callback a sample (10-40 us each). Compatible with QOS_FAST
#: publishers.
QOS_LINK = QoSProfile(history=QoSHistoryPolicy.KEEP_LAST, depth=1000,
                      reliability=QoSReliabilityPolicy.BEST_EFFORT,
                      durability=QoSDurabilityPolicy.VOLATILE)
#: a 1 kHz state sampled at a lower rate by its consumer (the camera's 30 Hz frames take the
#: robot's newest joint state): best effort, keep last 1. A consumer that is busy or preempted
#: for a while takes one message afterwards, not the ten stale ones QOS_FAST would queue
#: (each a DDS take and a deserialisation in its process). Compatible with QOS_FAST publishers.
QOS_LATEST = QoSProfile(history=QoSHistoryPolicy.KEEP_LAST, depth=1,
                        reliability=QoSReliabilityPolicy.BEST_EFFORT,
                        durability=QoSDurabilityPolicy.VOLATILE)
#: on-demand topics (tip load, shape, diagnostics): reliable, keep last 10
QOS_DEFAULT = QoSProfile(history=QoSHistoryPolicy.KEEP_LAST, depth=10,
                         reliability=QoSReliabilityPolicy.RELIABLE,
                         durability=QoSDurabilityPolicy.VOLATILE)
#: an observing tool (catheter_topic echo / hz / bw): best effort, keep last 1000, volatile:
#: compatible with every publisher, also one discovered after the subscription, and deep
#: enough that a burst is counted, not dropped by the tool's own queue
QOS_OBSERVE = QoSProfile(history=QoSHistoryPolicy.KEEP_LAST, depth=1000,
                         reliability=QoSReliabilityPolicy.BEST_EFFORT,
                         durability=QoSDurabilityPolicy.VOLATILE)
