"""default_urdf: the one place that says which model a run without a robot file uses."""

from pathlib import Path

from replan_core.robot.robot_file import DEFAULT_URDF, default_urdf

ROOT = Path(__file__).resolve().parents[4]


def test_the_environment_wins(monkeypatch, tmp_path):
    monkeypatch.setenv('REPLAN_URDF', '/some/robot.urdf')
    assert default_urdf(ROOT) == '/some/robot.urdf'


def test_else_the_first_root_that_holds_it_else_the_first_root(monkeypatch, tmp_path):
    monkeypatch.delenv('REPLAN_URDF', raising=False)
    assert Path(default_urdf(ROOT)) == ROOT / 'urdf' / 'hyq.urdf'
    assert Path(default_urdf(tmp_path, ROOT)) == ROOT / DEFAULT_URDF      # tmp_path has none
    assert Path(default_urdf(tmp_path / 'a', tmp_path / 'b')) == tmp_path / 'a' / DEFAULT_URDF
    monkeypatch.setenv('REPLAN_URDF', '')                                   # empty: not set
    assert Path(default_urdf(ROOT)) == ROOT / DEFAULT_URDF
