"""The parameter files of a run: the gait's parameters (``gait_parameters``), the world
profile's file (``profile_file``), the robot's parameters (``robot_parameters``) and the check of
every file of the run against the nodes' parameter tables before anything starts
(``check_run_files``)."""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from replan_core.gait.gait_file import GaitFileError, gait_names, load_gait
from replan_ros.params import TABLES, Source, check_run, load_param_file, load_yaml
from replan_ros.params.robot import RobotLayer, project_root, robot_layer
from replan_ros.params.spec import ConfigError

PROFILES = ('realistic', 'ideal')
DEFAULT_PROFILE = 'realistic'
DEFAULT_ROBOT = 'hyq'
DEFAULT_GAIT = 'crawl'


def gait_parameters(config_dir: Path, gait: str) -> Source:
    """The gait ``gait`` (a name of ``config/gaits/``) as the gait node's parameters,
    in the reference robot's units: the first layer after the node files, so the profile, the
    robot's scaling and the user's files come on top (docs/gait.md, "Gait files"). ConfigError
    (one line naming the file and key) for an unknown gait or a file that cannot be used."""
    try:
        spec = load_gait(gait, config_dir)
    except GaitFileError as err:
        raise ConfigError(str(err)) from None
    return Source(f'gait {spec.name} (config/gaits/{spec.name}.yaml)',
                  {'gait': spec.node_parameters()})


def gait_library(config_dir: Path, profile: Path | None, layer: RobotLayer | None) -> str:
    """Every gait of ``config/gaits/`` as the gait node's values for the run's robot (each
    gait's layer on the node files and the profile, scaled as the start gait's), as the gait
    node's ``gait_library`` parameter (JSON): what a run-time switch (gait_command) walks."""
    library = {}
    for name in gait_names(config_dir):
        source = gait_parameters(config_dir, name)
        keys = list(source.sections['gait'])
        reference = check_run_files(config_dir, [source, *([profile] if profile else [])])
        library[name] = (layer.gait_values(reference.values, keys) if layer is not None
                         else {key: reference.values['gait'][key] for key in keys})
    return json.dumps(library, sort_keys=True)


def write_source(source: Source, path: Path, header: str) -> Path:
    """A parameter source as a ROS parameter file (``node: {ros__parameters: ...}``)."""
    doc = {node: {'ros__parameters': dict(values)} for node, values in source.sections.items()}
    path.write_text(header + yaml.safe_dump(doc, sort_keys=False))
    return path


def profile_file(config_dir: Path, profile: str) -> Path:
    """The parameter file of a profile: a name in ``config/profiles/`` or a path."""
    path = Path(profile)
    if path.suffix in ('.yaml', '.yml'):
        if not path.is_file():
            raise ValueError(f'profile file {path} does not exist')
        return path
    path = config_dir / 'profiles' / f'{profile}.yaml'
    if not path.is_file():
        known = sorted(p.stem for p in (config_dir / 'profiles').glob('*.yaml'))
        raise ValueError(f'unknown profile {profile!r} (known: {", ".join(known)})')
    return path


def check_run_files(config_dir: Path, param_files, extra_params=None):
    """Check the node files of ``config_dir``, then ``param_files`` in order (the profile and
    the user's files: paths, or ``params.Source`` for parameters not in a file yet), then the
    ``-p`` values of ``extra_params`` ({node: {name: text}}), against the parameter tables and
    each other; returns the effective values (``params.Resolved``). ConfigError names the
    file, the node, the key, the value and what is allowed."""
    sources = []
    for name in TABLES:
        path = config_dir / f'{name}.yaml'
        if path.is_file():
            sources.append(Source(str(path), load_param_file(path), nodes=(name,)))
    sources += [item if isinstance(item, Source) else Source(str(item), load_param_file(item))
                for item in param_files]
    for name, values in (extra_params or {}).items():
        sources.append(Source('command line (-p)', {
            name: {key: load_yaml(str(text)) for key, text in values.items()}}, nodes=(name,)))
    return check_run(sources, TABLES)


def robot_parameters(config_dir: Path, robot: str, profile: Path | None,
                     gait: Source | None = None) -> RobotLayer:
    """The parameters of ``robot`` (a name of ``config/robots/`` or a robot file) for a run in
    ``profile`` and ``gait`` (``gait_parameters``): derived from the reference robot's values of
    the node files, the gait and the profile (docs/robot_files.md, "Scaling rules").
    ConfigError (one line) for an unknown robot or a robot file whose names do not match its
    model."""
    reference = check_run_files(config_dir, [item for item in (gait, profile)
                                             if item is not None])
    return robot_layer(robot, config_dir, project_root(), reference.values)
