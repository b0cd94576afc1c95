"""The tests' fake camera as a node module (importable by a worker process)."""
from nodes_for_tests import FakeCameraNode

NODE_CLASS = FakeCameraNode
