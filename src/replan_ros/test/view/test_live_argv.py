"""``--live [PORT]`` before a positional: the positional is not taken for the port."""

from replan_ros.launch.launch_graph import live_argv


def test_a_bare_live_before_a_file_gets_the_default_port():
    assert live_argv(['--live', 'config/scenarios/forward.yaml']) == [
        '--live=8765', 'config/scenarios/forward.yaml']
    assert live_argv(['--live', '--quiet']) == ['--live=8765', '--quiet']


def test_a_port_or_a_last_live_is_left_alone():
    assert live_argv(['--live', '9000', 'f.yaml']) == ['--live', '9000', 'f.yaml']
    assert live_argv(['f.yaml', '--live']) == ['f.yaml', '--live']
    assert live_argv(['--live=9001', 'f.yaml']) == ['--live=9001', 'f.yaml']
