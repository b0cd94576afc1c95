"""Messages the fam_solver node tests publish (importable: the folder's conftest puts it on
sys.path)."""
from geometry_msgs.msg import WrenchStamped


def wrench(fx, fy, mz=0.0, sec=7):
    """A tip load in the catheter's base frame: force (N), moment (N m), stamp ``sec``."""
    m = WrenchStamped()
    m.header.frame_id = 'catheter_base'
    m.header.stamp.sec = sec
    m.wrench.force.x, m.wrench.force.y, m.wrench.torque.z = fx, fy, mz
    return m
