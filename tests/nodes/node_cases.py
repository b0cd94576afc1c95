"""The project's nodes as the tests of tests/nodes and tests/fuzz build them: name -> class,
and a factory that adds a node to a RosHarness with parameter overrides."""
import importlib

from rclpy.parameter import Parameter

#: executable / node name -> module defining NODE_CLASS
NODE_MODULES = {
    'fam_solver_node': 'fam_solver.fam_solver_node',
    'shape_node': 'catheter_shape.shape_node',
    'force_estimator_node': 'force_estimator.force_estimator_node',
    'sim_slave_node': 'sim_slave.sim_slave_node',
    'camera_node': 'sim_slave.camera_node',
    'impedance_identifier_node': 'impedance_master.impedance_identifier_node',
    'ima_master_node': 'impedance_master.ima_master_node',
    'sim_haptic_node': 'impedance_master.sim_haptic_node',
    'force_source_node': 'catheter_bringup.force_source_node',
}
#: the package of each node's executable (ros_ws/install/<pkg>/lib/<pkg>/<exe>)
NODE_PACKAGES = {name: mod.split('.')[0] for name, mod in NODE_MODULES.items()}
#: small settings that keep in-process instances cheap (the camera draws 800x800 otherwise)
LIGHT = {'camera_node': {'camera.width': 160, 'camera.height': 160, 'camera.base_px': [20.0, 80.0],
                         'camera.mm_per_px': 0.6}}


def node_class(name):
    return importlib.import_module(NODE_MODULES[name]).NODE_CLASS



def make_node(ros, name, namespace=None, light=True, **params):
    """Build node `name` in the harness's context (added to its executor)."""
    over = dict(LIGHT.get(name, {})) if light else {}
    over.update(params)
    kw = dict(context=ros.context,
              parameter_overrides=[Parameter(k, value=v) for k, v in over.items()])
    if namespace:
        kw['namespace'] = namespace
    return ros.add(node_class(name)(**kw))
