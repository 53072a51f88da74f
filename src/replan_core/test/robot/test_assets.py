"""model_assets: package:// names of the models' files resolve to the installed example-robot-data
and the project's urdf/, and nothing outside the served folders is ever read."""

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from replan_core.robot.assets import (
    AssetError,
    ModelAssets,
    package_file,
    served_model_assets,
    split_package_uri,
)
from replan_core.robot.robot_file import example_robot_data_dir, load_robot_file

ROOT = Path(__file__).resolve().parents[4]


def mesh_names(urdf: Path) -> list[str]:
    return sorted({m.get('filename') for m in ET.parse(urdf).getroot().iter('mesh')})


@pytest.mark.parametrize('robot', ['go1', 'b1', 'anymal_c', 'anymal_b', 'a1', 'go2'])
def test_every_mesh_of_the_example_robot_data_models_is_served(robot):
    spec = load_robot_file(ROOT / 'config' / 'robots' / f'{robot}.yaml', ROOT)
    assets = served_model_assets(ROOT)
    names = mesh_names(spec.urdf)
    assert names and all(n.startswith('package://') for n in names)
    for name in names:
        path = assets.path(name)
        assert path.is_relative_to(example_robot_data_dir().parent.resolve()), name


def test_both_ways_a_model_names_its_package():
    """example-robot-data's URDFs say package://example-robot-data/robots/..., some lines
    package://<robot>_description/...: both reach the same file."""
    assets = served_model_assets(ROOT)
    long = assets.path('package://example-robot-data/robots/b1_description/meshes/trunk.dae')
    short = assets.path('package://b1_description/meshes/trunk.dae')
    assert long == short
    assert assets.read('package://go1_description/meshes/hip.dae') == (
        example_robot_data_dir() / 'go1_description' / 'meshes' / 'hip.dae').read_bytes()


def test_the_project_urdf_folder_is_served_and_nothing_else_of_the_project():
    assets = served_model_assets(ROOT)
    assert assets.read('package://replan_ros/urdf/hyq.urdf') == (
        ROOT / 'urdf' / 'hyq.urdf').read_bytes()
    with pytest.raises(AssetError, match='outside the served model folders'):
        assets.read('package://replan_ros/config/robots/go1.yaml')


@pytest.mark.parametrize(('uri', 'why'), [
    ('file:///etc/passwd', 'only package:// URIs'),
    ('https://example.com/a.dae', 'only package:// URIs'),
    ('package://go1_description', 'expected package://PACKAGE/PATH'),
    ('package:///etc/passwd', 'expected package://PACKAGE/PATH'),
    ('package://go1_description/../../../../../../etc/passwd', 'stay inside its package'),
    ('package://go1_description/meshes/../urdf/go1.urdf', 'stay inside its package'),
    ('package://go1_description//etc/passwd', 'stay inside its package'),
    ('package://no_such_package/meshes/a.dae', "unknown package 'no_such_package'"),
    ('package://go1_description/meshes/no_such_mesh.dae', 'no such file'),
    ('package://go1_description/meshes', 'no such file'),          # a folder
])
def test_what_is_refused_and_why(uri, why):
    with pytest.raises(AssetError, match=why):
        served_model_assets(ROOT).read(uri)


def test_a_symlink_out_of_the_roots_is_refused(tmp_path):
    served = tmp_path / 'share' / 'pkg'
    (served / 'meshes').mkdir(parents=True)
    (served / 'meshes' / 'ok.stl').write_bytes(b'mesh')
    secret = tmp_path / 'secret.txt'
    secret.write_text('not yours')
    (served / 'meshes' / 'leak.stl').symlink_to(secret)
    (tmp_path / 'share' / 'outside').symlink_to(tmp_path, target_is_directory=True)
    assets = ModelAssets(roots=(served,), search=(tmp_path / 'share',))
    assert assets.read('package://pkg/meshes/ok.stl') == b'mesh'
    with pytest.raises(AssetError, match='outside the served model folders'):
        assets.read('package://pkg/meshes/leak.stl')
    with pytest.raises(AssetError, match='outside the served model folders'):
        assets.read('package://outside/secret.txt')     # a package folder that is a symlink


def test_split_and_package_file():
    assert split_package_uri('package://a-b/c/d.dae') == ('a-b', 'c/d.dae')
    here = Path(__file__).parent
    assert package_file(f'package://{here.name}/x.dae', (here.parent,)) == here / 'x.dae'
    assert package_file('package://p/x', (), {'p': Path('/q')}) == Path('/q/x')
    with pytest.raises(AssetError, match='unknown package'):
        package_file('package://nowhere_at_all/x', (here,))
