"""The simulated world's settings: the terrains and their default sizes (``TerrainSettings``),
the joint actuators (``ActuatorParams``), the world as a whole (``WorldSettings``:
``SimWorld.from_settings`` builds it) and the realistic profile's values. Numpy-free, so that the
ROS parameter tables read them without loading PyBullet."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

TERRAINS = ('flat', 'step_down', 'step_up', 'rough')
TERRAIN_DEFAULTS = {
    'step_x': 0.6,            # m, x of the step edge (step_down, step_up)
    'step_height': 0.1,       # m, drop (step_down) or rise (step_up)
    'step_length': 2.0,       # m, step_up box length along x
    'width': 4.0,             # m, extent along y (step_up, rough)
    'rough_start_x': 0.6,     # m, where the heightfield begins
    'rough_length': 4.0,      # m, extent along x
    'rough_amplitude': 0.03,  # m, heights uniform in [0, amplitude]
    'rough_resolution': 0.05,  # m, cell size
}


@dataclass(frozen=True)
class ActuatorParams:
    """Joint actuators between the torque command and the joint; the defaults are ideal.

    Per physics step the command (held over the control tick and clipped to the limits) is
    delayed by ``delay``, then low-passed with ``time_constant``: that is the actuator torque,
    reported as ``joint_state().effort``. Joint friction acts on top of it.
    """

    time_constant: float = 0.0        # s, first-order lag of the torque loop; 0 = none
    delay: float = 0.0                # s, transport delay, rounded to whole physics steps
    viscous_damping: float = 0.0      # N m s/rad, joint viscous friction
    coulomb_friction: float = 0.0     # N m, joint dry friction (smooth near qd = 0)
    torque_limit_scale: float = 1.0   # actuator limits = this x the URDF effort limits

    def __post_init__(self) -> None:
        values = (self.time_constant, self.delay, self.viscous_damping, self.coulomb_friction)
        if not all(math.isfinite(v) and v >= 0.0 for v in values):
            raise ValueError(f'actuator parameters must be finite and >= 0: {self}')
        if not (math.isfinite(self.torque_limit_scale) and self.torque_limit_scale > 0.0):
            raise ValueError(f'torque_limit_scale must be > 0, got {self.torque_limit_scale}')


@dataclass(frozen=True)
class TerrainSettings:
    """The ground: its type (one of ``TERRAINS``) and sizes (m; each type reads its own)."""

    kind: str = 'flat'
    step_x: float = TERRAIN_DEFAULTS['step_x']
    step_height: float = TERRAIN_DEFAULTS['step_height']
    step_length: float = TERRAIN_DEFAULTS['step_length']
    width: float = TERRAIN_DEFAULTS['width']
    rough_start_x: float = TERRAIN_DEFAULTS['rough_start_x']
    rough_length: float = TERRAIN_DEFAULTS['rough_length']
    rough_amplitude: float = TERRAIN_DEFAULTS['rough_amplitude']
    rough_resolution: float = TERRAIN_DEFAULTS['rough_resolution']

    def __post_init__(self) -> None:
        if self.kind not in TERRAINS:
            raise ValueError(f'terrain must be one of {TERRAINS}, got {self.kind!r}')

    def sizes(self) -> dict[str, float]:
        """The sizes by their ``TERRAIN_DEFAULTS`` names."""
        return {name: getattr(self, name) for name in TERRAIN_DEFAULTS}


@dataclass(frozen=True)
class WorldSettings:
    """The simulated world but for the robot's model and names: time steps, spawn pose,
    ground, contacts, actuators (``SimWorld.from_settings``; the sim node fills it from its
    parameters). The defaults are the ideal world's, and SimWorld's keywords' defaults."""

    physics_dt: float = 0.001            # s
    control_period: float = 0.004        # s, a multiple of physics_dt
    initial_joint_positions: tuple[float, ...] = ()   # rad, JOINT_NAMES order; (): HyQ's pose
    initial_base_height: float = 0.0     # m, base_link z; 0: feet just touching the ground
    terrain: TerrainSettings = field(default_factory=TerrainSettings)
    seed: int = 0                        # of the rough terrain's heights
    friction: float = 0.8                # foot/ground Coulomb friction coefficient
    contact_stiffness: float = 0.0       # N/m, of the foot contacts; 0: rigid
    contact_damping: float = 0.0         # N s/m, with a contact_stiffness
    contact_threshold: float = 30.0      # N, normal force for contact
    debounce_ticks: int = 2              # ticks above/below the threshold
    actuator: ActuatorParams = field(default_factory=ActuatorParams)
    gui: bool = False                    # open PyBullet's GUI


# Suggested values for HyQ (the defaults above are ideal):
# - time_constant 3 ms: a torque loop of ~50 Hz bandwidth, 1 / (2 pi 50 Hz), the order of the
#   hydraulic torque control of HyQ (Boaventura et al., ICRA 2012; figure from memory);
# - delay 2 ms: two 1 kHz cycles between the command and the valve (bus and valve dead time,
#   an estimate);
# - viscous_damping 0.1 N m s/rad: hyq_description's joint damping;
# - coulomb_friction 1 N m: cylinder seal friction of some tens of N on a ~0.04 m lever arm
#   (an estimate).
REALISTIC_ACTUATOR = ActuatorParams(time_constant=0.003, delay=0.002, viscous_damping=0.1,
                                    coulomb_friction=1.0)
# Rubber feet: Hertz contact of HyQ's 0.02175 m foot sphere, rubber E ~ 5 MPa (nu 0.5), under a
# quarter of the weight (213 N): 3 mm compression, tangent stiffness 1.5 F / delta ~ 1e5 N/m;
# damping 2 sqrt(k m) for the ~0.9 kg lower leg (critical: a landing foot does not bounce).
REALISTIC_CONTACT_STIFFNESS = 1.0e5     # N/m
REALISTIC_CONTACT_DAMPING = 600.0       # N s/m
