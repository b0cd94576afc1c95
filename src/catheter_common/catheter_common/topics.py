"""Topic names and frame ids of the catheter node graph (DESIGN section 4).

One place for every name, so nodes, the recorder, the analysis and tests agree. Pure
Python (no rclpy): algorithm modules and offline tools import it too. The QoS profiles
that go with the topics are in `catheter_common.qos` (which needs rclpy).

The constants are the names in the root namespace (what a recording of an un-namespaced
graph holds). Nodes create their publishers and subscriptions with `relative(name)`, so
`--ros-args -r __ns:=/robot1` (or `namespace=` in-process) moves the whole graph under
/robot1; the ROS-wide topics in `GLOBAL` (/clock, /diagnostics, /tf, ...) stay absolute,
where ROS tools expect them. `resolve(name, ns)` gives the name a topic has under `ns`.
"""

# Frames
FRAME_CATHETER_BASE = 'catheter_base'
FRAME_CAMERA = 'camera_optical_frame'

# Topics
CAMERA_IMAGE = '/camera/image_raw'             # sensor_msgs/Image, mono8, 30 Hz
CONTROL_POINTS = '/catheter/control_points'    # geometry_msgs/PoseArray, 4 poses base->tip
TIP_LOAD = '/catheter/tip_load'                # geometry_msgs/WrenchStamped (input of fam_solver)
#: nav_msgs/Path: the centreline MEASURED in the image (shape_node)
SHAPE = '/catheter/shape'
#: nav_msgs/Path: the centreline MODELLED by FAM from the tip load (fam_solver_node)
FAM_SHAPE = '/catheter/fam/shape'
FAM_SHAPE_MARKER = '/catheter/fam/shape_marker'  # visualization_msgs/Marker of FAM_SHAPE
#: former name of FAM_SHAPE_MARKER (kept until every user says FAM_SHAPE_MARKER)
SHAPE_MARKER = FAM_SHAPE_MARKER
#: geometry_msgs/WrenchStamped: the estimated tip force, NORMAL estimates only (what controllers
#: and the force source use)
TIP_WRENCH = '/catheter/tip_wrench'
#: catheter_interfaces/TipForceEstimate: EVERY estimate with its covariance, domain status,
#: method and domain distance (force_estimator_node)
TIP_FORCE = '/catheter/tip_force'
SHAPE_DEBUG_IMAGE = '/catheter/debug_image'    # sensor_msgs/Image overlay (only while subscribed)
#: sensor_msgs/JointState (insertion m, rotation rad; effort N)
SLAVE_JOINT_STATE = '/slave/joint_state'
#: sensor_msgs/JointState: /slave/joint_state decimated (sim_slave_node's `decimated_rate`,
#: 100 Hz: the first state of each period), for the 30 Hz camera in another process
SLAVE_JOINT_STATE_DECIMATED = '/slave/joint_state_decimated'
#: /slave/joint_state with the insertion effort taken from the image-based tip force
#: (force_source_node; the identifier's input when a scenario says force_source: image)
SLAVE_JOINT_STATE_IMAGE = '/slave/joint_state_image'
#: catheter_interfaces/ImpedanceModel: the identified environment model
SLAVE_IMPEDANCE = '/slave/impedance'
SLAVE_FORCE = '/slave/force'                   # geometry_msgs/WrenchStamped
#: catheter_interfaces/MasterCommand: position, velocity, acceleration of the master handle
MASTER_COMMAND = '/master/command'
MASTER_RENDERED_FORCE = '/master/rendered_force'  # geometry_msgs/WrenchStamped
# The simulated UDP-like link: each side's sim node receives the other side's streams through
# its side of the link (delay, jitter, loss, outages, latest-wins) and republishes what was
# delivered on these master-local topics, which the renderer consumes.
MASTER_LINK_IMPEDANCE = '/master/link/impedance'  # /slave/impedance as delivered at the master
MASTER_LINK_FORCE = '/master/link/force'          # /slave/force as delivered at the master
#: geometry_msgs/WrenchStamped: force at the operator's hand
MASTER_HAND_FORCE = '/master/hand_force'
#: geometry_msgs/WrenchStamped: tip force the sim camera drew
CAMERA_TIP_FORCE_TRUTH = '/camera/tip_force_truth'
DIAGNOSTICS = '/diagnostics'                   # diagnostic_msgs/DiagnosticArray
CLOCK = '/clock'                               # rosgraph_msgs/Clock

# The base names of impedance_master.impedance.Impedance.to_fields() (the model's scalar fields;
# on the wire: catheter_interfaces/ImpedanceModel, converted by catheter_common.messages).
IMPEDANCE_FIELDS = ('m', 'c', 'k', 'offset', 'valid')

#: ROS-wide topics: absolute in every namespace (ROS tools look for them there)
GLOBAL = frozenset({CLOCK, DIAGNOSTICS, '/rosout', '/parameter_events', '/tf', '/tf_static'})


def relative(name: str) -> str:
    """The name a node creates its publisher or subscription with: relative (no leading '/')
    so the node's namespace applies, except for the ROS-wide topics in `GLOBAL`."""
    if not isinstance(name, str) or not name.startswith('/') or len(name) < 2:
        raise ValueError(f'name must be an absolute topic name like "/slave/force", got {name!r}')
    return name if name in GLOBAL else name[1:]


def resolve(name: str, namespace: str = '/') -> str:
    """The fully qualified name of topic `name` (a constant of this module) for nodes in
    `namespace`: resolve('/slave/force', '/robot1') == '/robot1/slave/force';
    the `GLOBAL` topics do not move."""
    rel = relative(name)
    if rel.startswith('/'):
        return rel
    if not isinstance(namespace, str) or not namespace.startswith('/'):
        raise ValueError(f'namespace must start with "/", got {namespace!r}')
    ns = namespace.rstrip('/')
    return f'{ns}/{rel}'
