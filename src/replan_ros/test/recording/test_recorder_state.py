"""The recorder's topic selection (``recorder_state.TopicSelection``), without a node."""

from replan_ros.recording.recorder_state import TopicSelection, is_hidden


def test_everything_but_hidden_by_default():
    select = TopicSelection([], '', '', False)
    assert select('/odom') and select('/view/zmp')
    assert is_hidden('/_private/x') and not select('/_private/x')
    assert TopicSelection([], '', '', True)('/_private/x')


def test_names_or_regex_select_exclude_wins():
    select = TopicSelection(['/odom', ''], '^/(imu|contacts)$', '^/contacts$', False)
    assert select('/odom') and select('/imu')
    assert not select('/contacts') and not select('/joint_states')
    assert not TopicSelection([], '', '^/tf$', False)('/tf')
