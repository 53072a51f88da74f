"""The MPC's settings, ``MpcSettings`` (the mpc node fills them from its parameters): numpy only,
so that the ROS parameter tables read their defaults without loading the QP solver."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from replan_core.common.types import GRAVITY

if TYPE_CHECKING:
    from replan_core.mpc.support import SupportSchedule


@dataclass
class MpcSettings:
    """Parameters of the re-planner (the node reads them from ``config/mpc.yaml``)."""

    dt: float = 0.04                  # s, sampling = constant-jerk interval
    horizon: float = 8.0              # s
    com_height: float = 0.55          # m, above the mean stance foot height (eq. 1)
    gravity: float = GRAVITY          # m/s^2
    jerk_weight: float = 1.0          # R of eq. (6)
    velocity_weight: float = 0.0      # weight of sum |v_k - v_ref|^2; 0 disables the term
    # weight (1/m^2 against R) of sum |p_k - c_k|^2, c_k the centre of the four feet at sample
    # k (SupportSchedule.centres); 0 disables the term. Not in the paper: its QP has no
    # position target, so the CoM stays wherever the support left it (docs/mpc.md).
    position_weight: float = 0.0
    # the position term's reference between the centre of the four feet (0) and the centroid
    # of the feet in stance (1: the CoM pulled into each support triangle, a sway)
    position_sway: float = 0.0
    # m, body frame x, y: where the CoM stands relative to the centre of the feet in the robot's
    # standing pose. The footholds are laid out about the base, so the term's reference is the
    # centre plus this offset turned with the trunk's yaw reference: without it the term pulls
    # the CoM off its place over the feet (HyQ's is 3.9 cm ahead) and an in-place turn crabbed
    # (docs/mpc.md, "Position term").
    com_offset: tuple[float, float] = (0.0, 0.0)
    zmp_margin: float = 0.0           # m, inward safety margin of every polygon
    # m, width of the strip about the segment of two stance feet (a trot's diagonal, the line
    # support of support.py; docs/mpc.md); 0: two feet are a degenerate polygon (the crawl)
    line_support_width: float = 0.0
    terminal_capture_point: bool = True   # capture point at N inside the last polygon
    formulation: str = 'working_set'  # 'working_set' (default), 'sparse' or 'dense' (lip_mpc.py)
    eps_abs: float = 1e-6             # proxsuite absolute tolerance
    max_iter: int = 200               # proxsuite iterations per solve
    warm_start: bool = True           # warm start from the previous solution shifted in time
    violation_tol: float = 1e-4       # m, a "solved" plan may violate a row by at most this
    slack_weight: float = 1e6         # cost per m (and m^2) of row violation in the fallback
    max_rounds: int = 30              # working set: row-adding rounds before giving up
    drop_inactive: bool = True        # working set: drop rows whose multiplier is 0
    add_peaks_only: bool = True       # working set: add rows only where the violation peaks
    working_set_tol: float = 1e-6     # m, working set: a row violated by more is added
    dual_mu_in: float = 1e-1          # proxsuite mu_in of the working-set dual
    # Working set: give up (and take the relaxed fallback) once the duals of one solve have
    # used this many iterations (active-set iterations of _nnqp, proxsuite's with
    # exact_dual=False). A feasible re-plan uses 5-65 active-set iterations (30-75 proxsuite
    # ones; bench_mpc.sh); the dual of an infeasible one is unbounded and each proxsuite solve
    # of it runs ~10000, so without the budget an infeasible re-plan took 4-11 s
    # (test_bad_input.py) while the robot waited.
    iteration_budget: int = 2000
    # Working set: solve each restricted dual exactly by an active-set method (a few small
    # LAPACK Cholesky solves, see _nnqp) instead of proxsuite; False: proxsuite + KKT polish
    # (the previous default, kept for comparison: bench_mpc.sh --proxsuite-dual).
    exact_dual: bool = True

    @property
    def n(self) -> int:
        return round(self.horizon / self.dt)

    def position_reference(self, sched: SupportSchedule) -> np.ndarray:
        """(N, 2) m: the CoM position the position term pulls to at each sample (``sched``
        made with ``support_schedule(..., centres=True)``)."""
        ref = sched.centres
        if self.position_sway != 0.0:
            ref = ref + self.position_sway * (sched.stance_centres - sched.centres)
        dx, dy = self.com_offset
        if dx != 0.0 or dy != 0.0:
            cos, sin = np.cos(sched.yaws), np.sin(sched.yaws)
            ref = ref + np.column_stack([cos * dx - sin * dy, sin * dx + cos * dy])
        return ref
