"""bench_speed's ``--robot``: the command line, the robot of each part (physics alone, the MPC
benchmark's crawl, the graph's launcher) through the project's own resolution, and the refusal
of a robot that cannot be used, in one ``config error:`` line before anything runs. No graph and
no physics are run here: the robot files and models are the real ones."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from replan_core.bench.sim_bench import PD_GAINS
from replan_core.robot.robot_file import RobotFileError
from replan_experiments.benchmarks.bench_speed import (
    CONFIG,
    SETUPS,
    header,
    json_line,
    main,
    parse_args,
    speed_robot,
    summarise,
    walk_scenario,
)
from replan_ros.launch.graph import EXIT_CONFIG
from replan_ros.params import ConfigError


def test_robot_option_defaults_to_hyq_and_takes_a_name_or_a_file():
    assert parse_args([]).robot == 'hyq'
    args = parse_args(['--robot', 'go1', '--runs', '1', '--duration', '4'])
    assert (args.robot, args.runs, args.duration) == ('go1', 1, 4.0)
    assert parse_args(['--robot', 'robots/b1.yaml']).robot == 'robots/b1.yaml'


def test_robot_option_needs_a_value(capsys):
    with pytest.raises(SystemExit) as stop:
        parse_args(['--robot'])
    assert stop.value.code == 2
    assert '--robot' in capsys.readouterr().err


def test_hyq_keeps_the_reference_values():
    robot = speed_robot('hyq')
    assert (robot.name, robot.given) == ('hyq', 'hyq')
    assert robot.physics.urdf.endswith('urdf/hyq.urdf')
    assert robot.physics.pd_gains == pytest.approx(PD_GAINS)
    assert robot.crawl.com_height is None            # the MPC keeps its tuned LIP height
    assert robot.crawl.speed_scale == 1.0


def test_every_part_runs_the_named_robot():
    robot = speed_robot('go1')
    assert (robot.name, robot.given) == ('go1', 'go1')
    assert robot.physics.urdf.endswith('go1.urdf')
    assert robot.physics.joints[0] == 'FL_hip_joint'
    assert robot.physics.pd_gains[0] < PD_GAINS[0] / 5     # m g l: Go1 is far lighter
    assert robot.crawl.com_height is not None and robot.crawl.com_height < 0.4
    assert robot.crawl.speed_scale < 1.0


def test_a_robot_file_given_by_path_is_named_by_its_name():
    path = str(CONFIG / 'robots' / 'go1.yaml')
    robot = speed_robot(path)
    assert (robot.name, robot.given) == ('go1', path)


def test_each_robot_benches_its_own_walk():
    """The graph benches walk a robot's own forward scenario (its robot-appropriate set-point,
    the one docs/robots.md measures), HyQ the 0.15 m/s of forward.yaml."""
    assert walk_scenario('hyq').name == 'forward.yaml'
    assert walk_scenario(str(CONFIG / 'robots' / 'go1.yaml')).name == 'go1_forward.yaml'
    for path in (CONFIG / 'robots').glob('*.yaml'):
        doc = yaml.safe_load(path.read_text())
        if path.stem in ('scaling', 'hyq'):
            continue
        walk = walk_scenario(doc['name'])
        assert walk.name == f'{doc["name"]}_forward.yaml', path
        assert yaml.safe_load(walk.read_text())['robot'] == doc['name']


def test_a_robot_without_a_walk_is_refused_not_sent_on_hyqs(tmp_path):
    """An unknown name or a robot file that does not fit its model is the launcher's one-line
    refusal, not HyQ's walk run with a robot that then cannot start."""
    with pytest.raises(RobotFileError, match="unknown robot 'nosuch'"):
        walk_scenario('nosuch')
    broken = tmp_path / 'my_go1.yaml'
    broken.write_text((CONFIG / 'robots' / 'go1.yaml').read_text().replace(
        'FL_hip_joint', 'FL_hip_jont'))
    with pytest.raises(RobotFileError, match='FL_hip_jont'):
        walk_scenario(str(broken))


def test_header_and_json_name_the_robot(tmp_path):
    assert header('go1', 1, 4.0, tmp_path).startswith('bench_speed: robot go1, 1 rounds, '
                                                      'walk go1_forward 4 sim s, ')
    assert header('hyq', 1, 4.0, tmp_path).startswith('bench_speed: robot hyq, 1 rounds, '
                                                      'walk forward 4 sim s, ')
    rtf = dict.fromkeys(SETUPS, 2.0)
    rounds = [{'physics': {'ideal': 9.0, 'realistic': 8.0},
               'graph': {s: {'real_time_factor': rtf[s], 'exit_code': 0, 'mpc': {}}
                         for s in SETUPS}}]
    mpc = {'median_ms': 1.0, 'p99_ms': 2.0, 'cpu_median_ms': 0.9}
    idle = {'idle_s': 0.3, 'median_ms': 2.0, 'p99_ms': 3.0, 'cpu_median_ms': 1.9}
    summary = summarise(rounds, mpc, idle)[1]
    line = json.loads(json_line('go1', summary, rounds, mpc, idle))
    assert line['robot'] == 'go1'
    assert line['mpc_bench'] == mpc


def _refused(capsys, argv: list[str], out: Path) -> str:
    assert main([*argv, '--out', str(out)]) == EXIT_CONFIG
    captured = capsys.readouterr()
    assert captured.out == ''
    assert not out.exists()                              # nothing started, nothing written
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith('config error: '), captured.err
    return lines[0]


def test_an_unknown_robot_stops_in_one_line_before_anything_runs(capsys, tmp_path):
    line = _refused(capsys, ['--robot', 'nosuch'], tmp_path / 'run')
    assert line == ("config error: unknown robot 'nosuch' (known: a1, anymal_b, anymal_c, b1, "
                    "go1, go2, hyq; or a robot file, docs/robot_files.md)")


def test_the_command_prints_only_the_config_error(tmp_path):
    """As a process: no PyBullet banner or anything else before the one line."""
    done = subprocess.run([sys.executable, '-m', 'replan_experiments.benchmarks.bench_speed',
                           '--robot', 'nosuch', '--out', str(tmp_path / 'run')],
                          capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)
    assert done.returncode == EXIT_CONFIG
    assert done.stdout == ''
    assert done.stderr.splitlines() == [
        "config error: unknown robot 'nosuch' (known: a1, anymal_b, anymal_c, b1, go1, go2, "
        "hyq; or a robot file, docs/robot_files.md)"]
    assert not (tmp_path / 'run').exists()


def test_a_robot_file_that_does_not_fit_its_model_is_refused(capsys, tmp_path):
    text = (CONFIG / 'robots' / 'go1.yaml').read_text()
    bad = tmp_path / 'bad.yaml'
    bad.write_text(text.replace('FL_calf_joint', 'FL_knee_joint'))
    line = _refused(capsys, ['--robot', str(bad)], tmp_path / 'run')
    assert str(bad) in line and 'FL_knee_joint' in line
    with pytest.raises(ConfigError):
        speed_robot(str(tmp_path / 'missing.yaml'))
