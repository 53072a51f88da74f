"""Every node parameter in one place: each node declares its parameters from its
table (``declare``), the launcher and the scenario runner check every parameter file of a run
against the same tables before anything starts (``files.check_run``), and each node repeats the
check on its own command line, so a bad value stops the start with one line naming the file,
the node, the key, the value and what is allowed (``config error: /tmp/x.yaml:
gait.replan_window = 0 is out of range [1, 8]``); ``spec`` holds ``ParamSpec`` and the value
checks, ``tables`` the per-node tables (their defaults read from the core's settings modules,
numpy only: importing this package loads neither pinocchio, proxsuite nor PyBullet),
``convert`` the one conversion of checked values into the core's dataclasses. This module
re-exports the public names of all of them.
"""

from __future__ import annotations

from replan_ros.params.convert import (
    MPC_FIXED,
    actuator_params,
    dataclass_from_params,
    estimator_params,
    gait_params,
    imu_noise_params,
    joint_sensor_params,
    mpc_settings,
    protocol_params,
    terrain_settings,
    wbc_params,
    world_settings,
)
from replan_ros.params.declare import declare_node_parameters
from replan_ros.params.files import (
    Resolved,
    Source,
    check_run,
    cross_node_checks,
    load_param_file,
    load_yaml,
    parse_param_doc,
    resolve,
    sources_from_argv,
)
from replan_ros.params.spec import (
    BUILTIN,
    INF,
    KINDS,
    RESTART_HINT,
    ConfigError,
    ParamSpec,
    check_value,
)
from replan_ros.params.tables import (
    GAIT,
    LIVE_VIEW,
    MPC,
    RECORDER,
    SIM,
    TABLES,
    WBC,
    defaults,
    table,
)

__all__ = [
    'BUILTIN', 'GAIT', 'INF', 'KINDS', 'LIVE_VIEW', 'MPC', 'MPC_FIXED', 'RECORDER',
    'RESTART_HINT', 'SIM', 'TABLES', 'WBC', 'ConfigError', 'ParamSpec', 'Resolved', 'Source',
    'actuator_params', 'check_run', 'check_value', 'cross_node_checks', 'dataclass_from_params',
    'declare_node_parameters', 'defaults', 'estimator_params', 'gait_params',
    'imu_noise_params', 'joint_sensor_params', 'load_param_file', 'load_yaml', 'mpc_settings',
    'parse_param_doc', 'protocol_params', 'resolve', 'sources_from_argv', 'table',
    'terrain_settings', 'wbc_params', 'world_settings',
]

