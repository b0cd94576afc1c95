"""force_estimator_node, method fam: the FAM inversion's parameters (length, ei, n_arcs,
f_max) apply at run time (module doc: "all apply at run time, from the next message")."""
import pytest
from rclpy.parameter import Parameter

from force_estimator.force_estimator_node import NODE_CLASS

pytestmark = pytest.mark.ros


def test_fam_parameters_rebuild_the_inversion(ros):
    node = ros.add(NODE_CLASS(context=ros.context, parameter_overrides=[
        Parameter('method', value='fam'), Parameter('n_arcs', value=8)]))
    first = node.estimator
    assert first.n_arcs == 8 and first.cat.length == 0.065
    for name, value in (('n_arcs', 6), ('length', 0.05), ('ei', 5e-5), ('f_max', 0.3)):
        assert node.set_parameters([Parameter(name, value=value)])[0].successful, name
    est = node.estimator
    assert est is not first
    assert (est.n_arcs, est.cat.length, est.cat.ei, est.f_max) == (6, 0.05, 5e-5, 0.3)
