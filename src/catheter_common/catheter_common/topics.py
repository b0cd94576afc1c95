"""Topic names and frame ids of the catheter node graph (DESIGN section 4).

One place for every name, so nodes, the recorder, the analysis and tests agree. Pure
Python (no rclpy): algorithm modules and offline tools import it too. The QoS profiles
that go with the topics are in `catheter_common.qos` (which needs rclpy).
"""

# Frames
FRAME_CATHETER_BASE = 'catheter_base'
FRAME_CAMERA = 'camera_optical_frame'

# Topics
CAMERA_IMAGE = '/camera/image_raw'             # sensor_msgs/Image, mono8, 30 Hz
CONTROL_POINTS = '/catheter/control_points'    # geometry_msgs/PoseArray, 4 poses base->tip
TIP_LOAD = '/catheter/tip_load'                # geometry_msgs/WrenchStamped (input of fam_solver)
SHAPE = '/catheter/shape'                      # nav_msgs/Path
SHAPE_MARKER = '/catheter/shape_marker'        # visualization_msgs/Marker
TIP_WRENCH = '/catheter/tip_wrench'            # geometry_msgs/WrenchStamped (estimated tip force)
SHAPE_DEBUG_IMAGE = '/catheter/debug_image'    # sensor_msgs/Image overlay (only while subscribed)
SLAVE_JOINT_STATE = '/slave/joint_state'       # sensor_msgs/JointState (insertion m, rotation rad; effort N)
SLAVE_IMPEDANCE = '/slave/impedance'           # sensor_msgs/JointState used as stamped named float64 values
SLAVE_FORCE = '/slave/force'                   # geometry_msgs/WrenchStamped
MASTER_COMMAND = '/master/command'             # sensor_msgs/JointState
MASTER_RENDERED_FORCE = '/master/rendered_force'  # geometry_msgs/WrenchStamped
# The simulated UDP-like link: each side's sim node receives the other side's streams through
# its side of the link (delay, jitter, loss, outages, latest-wins) and republishes what was
# delivered on these master-local topics, which the renderer consumes.
MASTER_LINK_IMPEDANCE = '/master/link/impedance'  # /slave/impedance as delivered at the master
MASTER_LINK_FORCE = '/master/link/force'          # /slave/force as delivered at the master
MASTER_HAND_FORCE = '/master/hand_force'        # geometry_msgs/WrenchStamped: force at the operator's hand
CAMERA_TIP_FORCE_TRUTH = '/camera/tip_force_truth'  # geometry_msgs/WrenchStamped: tip force the sim camera drew
DIAGNOSTICS = '/diagnostics'                   # diagnostic_msgs/DiagnosticArray
CLOCK = '/clock'                               # rosgraph_msgs/Clock

# Names of the values carried in /slave/impedance (JointState.name, values in JointState.position).
IMPEDANCE_FIELDS = ('m', 'c', 'k', 'offset', 'valid')
