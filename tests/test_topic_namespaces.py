"""Every node's topics follow its namespace and remappings, with no doubled prefix (#16 item 7).

The nodes run in-process with real rclpy; a probe reads the resolved names from the ROS graph
(get_publisher_names_and_types_by_node / get_subscriber_names_and_types_by_node), so what is
checked is what rcl resolved, not what the code meant. Waits on graph conditions only.
"""

from __future__ import annotations

import pytest
from camera_captures import write_captures
from ros_fixtures import REPO_ROOT
from ros_waiting import wait_until

pytestmark = pytest.mark.ros

TIMEOUT = 120.0  # [s] generous: correlation_node subscribes only after its kernel warm-up
GLOBAL_TOPICS = {'/diagnostics', '/tf_static', '/rosout', '/parameter_events'}
PERCEPTION = REPO_ROOT / 'src' / 'stereo_fuzzy_perception'


class Graph:
    """Nodes under test plus a probe that reads their resolved topic names from the graph."""

    def __init__(self, context) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        self.probe = rclpy.create_node('namespace_probe', context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.probe)
        self.nodes: list = []

    def add(self, node) -> None:
        self.nodes.append(node)
        self.executor.add_node(node)

    def topics(self, node) -> tuple[set[str], set[str]]:
        """Return the (published, subscribed) topic names of `node` as the graph shows them."""
        name, namespace = node.get_name(), node.get_namespace()
        published = self.probe.get_publisher_names_and_types_by_node(name, namespace)
        subscribed = self.probe.get_subscriber_names_and_types_by_node(name, namespace)
        return {topic for topic, _ in published}, {topic for topic, _ in subscribed}

    def wait_for(self, node, published: set[str], subscribed: set[str]) -> None:
        """Wait until the graph shows `node` with at least these topics."""
        def shown() -> bool:
            try:
                have_published, have_subscribed = self.topics(node)
            except Exception:  # the node is not on the graph yet
                return False
            return published <= have_published and subscribed <= have_subscribed
        wait_until(shown, TIMEOUT, f'{node.get_fully_qualified_name()} to show '
                   f'{sorted(published)} / {sorted(subscribed)}', self.executor)

    def close(self) -> None:
        self.executor.shutdown()
        for node in (*self.nodes, self.probe):
            node.destroy_node()


@pytest.fixture
def graph(ros_context):
    made = Graph(ros_context)
    yield made
    made.close()


def assert_no_doubled_prefix(graph: Graph, namespace: str) -> None:
    doubled = f'{namespace}{namespace}/'
    for node in graph.nodes:
        published, subscribed = graph.topics(node)
        for topic in published | subscribed:
            assert doubled not in topic, f'{node.get_name()}: {topic} doubles {namespace}'
            assert topic in GLOBAL_TOPICS or topic.startswith(f'{namespace}/'), (
                f'{node.get_name()}: {topic} does not follow its namespace {namespace}')


def test_every_node_pushed_into_a_namespace_takes_all_its_topics_along(graph, ros_context,
                                                                        tmp_path):
    from rclpy.parameter import Parameter
    from stereo_fuzzy_perception.nodes.correlation_node import CorrelationNode
    from stereo_fuzzy_perception.nodes.fuzzy_best_point_node import FuzzyBestPointNode
    from stereo_fuzzy_perception.nodes.rig_transforms_node import RigTransformsNode
    from stereo_fuzzy_perception.nodes.stereo_camera_node import StereoCameraNode
    from stereo_fuzzy_perception.nodes.stereo_sync_node import StereoSyncNode

    def parameters(values: dict) -> list:
        return [Parameter(name, value=value) for name, value in values.items()]

    namespace = '/stereo'
    camera = StereoCameraNode(context=ros_context, namespace=namespace,
                              parameter_overrides=parameters(write_captures(tmp_path, frames=1)))
    sync = StereoSyncNode(context=ros_context, namespace=namespace)
    correlation = CorrelationNode(context=ros_context, namespace=namespace)
    fuzzy = FuzzyBestPointNode(context=ros_context, namespace=namespace)
    transforms = RigTransformsNode(context=ros_context, namespace=namespace,
                                   parameter_overrides=parameters({
                                       'rig_pose_file': str(PERCEPTION / 'config' /
                                                            'demo_rig_pose.yaml')}))
    for node in (camera, sync, correlation, fuzzy, transforms):
        graph.add(node)
    cameras = {'/stereo/left/image_raw', '/stereo/left/camera_info', '/stereo/right/image_raw',
               '/stereo/right/camera_info'}
    graph.wait_for(camera, cameras, set())
    graph.wait_for(sync, {'/stereo/pair', '/diagnostics'}, cameras)
    graph.wait_for(correlation, {'/stereo/matches', '/stereo/points', '/stereo/disparity'},
                   {'/stereo/pair'})
    graph.wait_for(fuzzy, {'/stereo/best_point', '/stereo/best_point/decision',
                           '/stereo/best_point/markers'}, {'/stereo/matches', '/tf_static'})
    graph.wait_for(transforms, {'/tf_static'}, set())
    assert_no_doubled_prefix(graph, namespace)


def test_the_default_chain_description_gives_the_product_topic_names(graph, ros_context):
    """The camera_rig set as launch_chain / ros2 launch start it: /stereo/pair, /stereo/matches
    and /best_point, built from the description's own --ros-args."""
    from stereo_fuzzy_perception.bringup.chain_description import ros_arguments
    from stereo_fuzzy_perception.nodes.correlation_node import CorrelationNode
    from stereo_fuzzy_perception.nodes.fuzzy_best_point_node import FuzzyBestPointNode
    from stereo_fuzzy_perception.nodes.stereo_sync_node import StereoSyncNode

    from chain.processes import process_set, source_share_directory

    processes = process_set('camera_rig')
    arguments = processes.argument_values()
    classes = {'stereo_sync_node': StereoSyncNode, 'correlation_node': CorrelationNode,
               'fuzzy_best_point_node': FuzzyBestPointNode}
    nodes = {process.name: classes[process.name](
        context=ros_context,
        cli_args=ros_arguments(process, arguments, source_share_directory))
        for process in processes.processes}
    for node in nodes.values():
        graph.add(node)
    assert nodes['stereo_sync_node'].get_namespace() == '/stereo'
    graph.wait_for(nodes['stereo_sync_node'], {'/stereo/pair'},
                   {'/stereo/left/image_raw', '/stereo/right/camera_info'})
    graph.wait_for(nodes['correlation_node'], {'/stereo/matches'}, {'/stereo/pair'})
    graph.wait_for(nodes['fuzzy_best_point_node'], {'/best_point', '/best_point/decision'},
                   {'/stereo/matches'})
    for node in nodes.values():
        published, subscribed = graph.topics(node)
        assert not any('/stereo/stereo' in topic for topic in published | subscribed), (
            node.get_name(), published, subscribed)
    # The set is wired: every topic a node reads (but the cameras' and the global ones) is one
    # another node of the set writes, e.g. correlation_node's /best_point/decision for roi.track.
    graph.wait_for(nodes['correlation_node'], set(), {'/best_point/decision'})
    topics = {name: graph.topics(node) for name, node in nodes.items()}
    written = set().union(*(published for published, _ in topics.values()))
    for name, (_, subscribed) in topics.items():
        unwired = {topic for topic in subscribed - written - GLOBAL_TOPICS
                   if not topic.startswith(('/stereo/left/', '/stereo/right/'))}
        assert not unwired, (name, unwired)
