"""Bad input without DDS: malformed tables and damaged bags (the soak's scenario and the
robustness page: replan_experiments' test_robustness.py). The same faults in a walking graph:
test/test_faults.py."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from mcap.exceptions import McapError
from mcap.reader import make_reader
from sensor_msgs.msg import PointCloud2, PointField
from test_bag_io import _write_bag

from replan_core.common.types import ContactState, FootholdPlan, Step
from replan_ros.messages.contacts import contact_events_from_msg, contacts_from_msg, contacts_to_msg
from replan_ros.messages.footholds import footholds_from_msg, footholds_to_msg
from replan_ros.recording.bag_io import check_bag


def _contacts_msg() -> PointCloud2:
    rng = np.random.default_rng(1)
    return contacts_to_msg(ContactState(0.5, rng.normal(size=(4, 3)), rng.normal(size=(4, 3)),
                                            np.ones(4, bool), np.zeros(4, bool),
                                            np.zeros(4, bool)))


def _footholds_msg() -> PointCloud2:
    feet = np.array([[0.37, 0.3, 0.0], [0.37, -0.3, 0.0], [-0.37, 0.3, 0.0], [-0.37, -0.3, 0.0]])
    steps = [Step(leg, 10.2 + i, 10.7 + i, feet[leg] + [0.1, 0, 0], 0.1, True, i == 0, 0.0)
             for i, leg in enumerate([2, 0, 3, 1])]
    return footholds_to_msg(FootholdPlan(10.0, feet, 0.0, steps, 0.4, 0.25))


def _with_float(msg: PointCloud2, row: int, field: str, value: float) -> PointCloud2:
    offset = next(f.offset for f in msg.fields if f.name == field)
    data = bytearray(msg.data)
    start = row * msg.point_step + offset
    data[start:start + 8] = np.float64(value).tobytes()
    msg.data = bytes(data)
    return msg


@pytest.mark.parametrize('field', ['y', 'z', 'liftoff_time', 'step_height', 'yaw'])
def test_footholds_with_any_non_finite_value_are_rejected(field):
    with pytest.raises(ValueError, match=f'non-finite {field}'):
        footholds_from_msg(_with_float(_footholds_msg(), 5, field, math.nan))


@pytest.mark.parametrize('field', ['x', 'fz'])
def test_contacts_with_non_finite_positions_or_forces_are_rejected(field):
    with pytest.raises(ValueError, match=f'non-finite {field}'):
        contacts_from_msg(_with_float(_contacts_msg(), 2, field, math.inf))


def test_a_table_shorter_than_its_header_says_is_one_clear_error():
    msg = _footholds_msg()
    msg.data = bytes(msg.data[:len(msg.data) // 2])
    with pytest.raises(ValueError, match='holds only'):
        footholds_from_msg(msg)


def test_a_table_with_an_unknown_datatype_or_a_bad_layout_is_one_clear_error():
    msg = _contacts_msg()
    fields = list(msg.fields)
    fields[0] = PointField(name='x', offset=0, datatype=99, count=1)
    msg.fields = fields
    with pytest.raises(ValueError, match='unsupported datatype'):
        contacts_from_msg(msg)
    msg = _contacts_msg()
    msg.point_step = 4                      # smaller than the fields it lists
    with pytest.raises(ValueError, match='does not fit point_step'):
        contacts_from_msg(msg)


def test_contact_events_naming_a_fifth_leg_are_rejected():
    msg = _contacts_msg()
    data = bytearray(msg.data)
    data[next(f.offset for f in msg.fields if f.name == 'leg')] = 4
    msg.data = bytes(data)
    with pytest.raises(ValueError, match=r'outside 0\.\.3'):
        contact_events_from_msg(msg)


def test_check_bag_reads_a_good_bag_and_names_a_damaged_one(tmp_path):
    good = tmp_path / 'good.mcap'
    _write_bag(good, 300, chunk_size=4096).close()
    assert check_bag(good) == 300
    data = bytearray(good.read_bytes())
    with open(good, 'rb') as stream:
        chunk = make_reader(stream).get_summary().chunk_indexes[2]
    middle = chunk.chunk_start_offset + chunk.chunk_length // 2
    data[middle:middle + 50] = bytes(b ^ 0x5A for b in data[middle:middle + 50])
    corrupt = tmp_path / 'corrupt.mcap'
    corrupt.write_bytes(bytes(data))
    with pytest.raises(McapError, match='corrupt or truncated after') as info:
        check_bag(corrupt)
    assert '\n' not in str(info.value)
    truncated = tmp_path / 'truncated.mcap'
    truncated.write_bytes(good.read_bytes()[:len(data) // 2])
    with pytest.raises(McapError):
        check_bag(truncated)


def test_an_infeasible_mpc_problem_gives_a_reason_and_a_safe_plan():
    """The CoM 1.5 m outside the feet at 1 m/s: no plan keeps the ZMP in the support. The core
    says why and where, and returns a relaxed plan flagged as fallback (the mpc node publishes
    it with WARN: test/test_mpc_node.py). Recorded for docs/robustness.md."""
    import os
    import time

    from replan_core.bench.mpc_bench import bench_crawl, crawl_plan
    from replan_core.mpc.lip_mpc import FALLBACK_RELAXED, STATUS_INFEASIBLE, LipMpc
    from replan_ros.params.robot import project_root

    layout = bench_crawl('hyq', project_root()).feet_xy       # m, HyQ's standing feet
    feet = np.column_stack([layout, np.zeros(4)])
    plan = crawl_plan(0.0, np.zeros(3), 0.0, feet, 2, np.zeros(2), np.random.default_rng(0),
                      layout=layout)
    mpc = LipMpc()
    start = time.perf_counter()
    res = mpc.solve(0.0, np.array([1.5, 0.0, 0.55]), np.array([1.0, 0.0, 0.0]), np.zeros(3),
                    plan)
    wall = time.perf_counter() - start
    assert res.status == STATUS_INFEASIBLE and res.fallback == FALLBACK_RELAXED
    assert 'eq. (7)' in res.reason or 'terminal' in res.reason, res.reason
    assert res.plan is not None and np.all(np.isfinite(res.plan.position))
    folder = Path(os.environ.get('REPLAN_ROBUSTNESS_DIR',
                                 Path(__file__).resolve().parents[4] / 'runs' / 'robustness'))
    folder.mkdir(parents=True, exist_ok=True)
    (folder / 'infeasible_mpc.json').write_text(json.dumps({
        'fault': 'an infeasible MPC problem (CoM 1.5 m outside the feet, 1 m/s)',
        'noticed_by': 'mpc (the QP)', 'diagnostics': f'{res.status}: {res.reason}',
        'safe_state': 'a slack-relaxed plan, flagged fallback; /diagnostics WARN',
        'time_to_safe_s': 0.0, 'recovery': 'the next re-plan from a feasible state',
        'time_to_walk_s': None, 'lowest_base_m': '',
        'data_lost': f'none (this solve took {wall:.2f} wall s here)'}, indent=1) + '\n')
