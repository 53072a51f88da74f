"""ListenersGate: the wbc's first estimate and command wait for the named nodes' readers, listed
in the graph and matched by the wbc's writers (a fake node: no DDS)."""

from types import SimpleNamespace

from replan_ros.transport.listeners import ListenersGate


class _Logger:
    def __init__(self):
        self.lines = []

    def info(self, text):
        self.lines.append(('info', text))

    def warning(self, text):
        self.lines.append(('warning', text))


class _Node:
    """The graph as a dict: topic -> reader node names."""

    def __init__(self):
        self.readers: dict[str, list[str]] = {}
        self.logger = _Logger()

    def resolve_topic_name(self, topic):
        return '/' + topic

    def get_subscriptions_info_by_topic(self, topic):
        return [SimpleNamespace(node_name=name) for name in self.readers.get(topic, [])]

    def count_subscribers(self, topic):
        return len(self.readers.get(topic, []))

    def get_logger(self):
        return self.logger


class _Publisher:
    def __init__(self):
        self.matched = 0

    def get_subscription_count(self):
        return self.matched


def test_a_listed_reader_not_yet_matched_keeps_the_gate_closed():
    # The graph lists a reader before the writer pairs with it; a sample published then never
    # reaches it, so listed is not enough.
    node, odom, cmd = _Node(), _Publisher(), _Publisher()
    gate = ListenersGate(node, {'odom': odom, 'joint_torque_cmd': cmd}, ['recorder'], 10.0)
    assert not gate.ready()
    node.readers = {'/odom': ['recorder', 'gait'], '/joint_torque_cmd': ['recorder', 'sim']}
    odom.matched, cmd.matched = 2, 1
    assert not gate.ready()                  # the recorder's command reader: not matched yet
    cmd.matched = 2
    assert gate.ready()
    assert node.logger.lines == [('info', "['recorder'] listen: starting")]
    node.readers = {}
    assert gate.ready()                      # open for good


def test_the_gate_opens_after_its_timeout_naming_what_is_missing():
    node, odom = _Node(), _Publisher()
    gate = ListenersGate(node, {'odom': odom}, ['recorder'], 0.0)
    assert gate.ready()
    assert node.logger.lines[0][0] == 'warning'
    assert 'no subscription of recorder on odom after first_command_wait_timeout (0 s)' \
        in node.logger.lines[0][1]
    node2, odom2 = _Node(), _Publisher()
    node2.readers = {'/odom': ['recorder']}
    gate = ListenersGate(node2, {'odom': odom2}, ['recorder'], 0.0)
    assert gate.ready()
    assert 'a reader of odom not matched after first_command_wait_timeout' \
        in node2.logger.lines[0][1]


def test_no_named_nodes_no_wait():
    node = _Node()
    assert ListenersGate(node, {'odom': _Publisher()}, [], 10.0).ready()
    assert node.logger.lines == []


def test_a_node_named_with_topics_is_waited_for_on_those_only():
    # A planner reads one topic of the estimate: it never subscribes to the others.
    node, odom, contacts = _Node(), _Publisher(), _Publisher()
    gate = ListenersGate(node, {'odom': odom, 'contacts': contacts},
                         ['gait=contacts+odom', 'mpc=odom'], 10.0)
    node.readers = {'/odom': ['mpc'], '/contacts': ['gait']}
    odom.matched = contacts.matched = 1
    assert gate.missing() == ['gait on odom']
    assert not gate.ready()
    node.readers['/odom'].append('gait')
    odom.matched = 2
    assert gate.ready()
    assert node.logger.lines == [('info', "['gait', 'mpc'] listen: starting")]


def test_an_entry_with_a_topic_not_published_is_refused():
    for entry in ('gait=footholds', '=odom', 'gait=odom+'):
        try:
            ListenersGate(_Node(), {'odom': _Publisher()}, [entry], 10.0)
        except ValueError as err:
            assert repr(entry) in str(err)
        else:
            raise AssertionError(entry)
