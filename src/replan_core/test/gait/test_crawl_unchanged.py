"""The crawl plan is bit-exact: general gaits (swing groups, line supports) leave it as it was.

The digests below are the crawl as it was when gaits were hard-coded (the Haswell set made from
the same code with Haswell's kernels). This file's ``__main__`` prints them:
``python src/replan_core/test/gait/test_crawl_unchanged.py``.
Each is the SHA-256 of every float and flag of a crawl's ``compute_footholds`` plan, its
``stance_phases`` and its MPC support schedule (rows and centres), over a fixed set of inputs.
A changed digest means the crawl's footholds, phases or polygons changed in some bit.
"""

from __future__ import annotations

import hashlib
import math
import os
from dataclasses import replace

import numpy as np

from replan_core.gait.crawl import GaitParams, compute_footholds, stance_phases
from replan_core.mpc.support import support_schedule

# One digest set per BLAS kernel class (OPENBLAS_CORETYPE, set by scripts/env.sh): OpenBLAS's
# SkylakeX and Haswell kernels differ in the last bits of a product.
EXPECTED = {
    'SkylakeX': {
        'footholds': '15887c7708d0f8531d1b53c3e950eb39a25e57f5f531ab1a255fa48e7dff239d',
        'phases': '59461187c130da94bcb4afc11c5047252f7e6beaf5a891de8304342f52e98ad3',
        'support': '1748edc522cdf80a95458109b14213395ee045d07598f416f93f0dbcd7a35914',
    },
    'Haswell': {
        'footholds': 'abc6bfa58a37bdf77774172fad9ecfdbf8751ef76e701fbae835c0c24bbdf40f',
        'phases': 'fe102528c0bda4848f4c312e9bc915c3565e2c8cf6a8d91e4af1aa61e4f21e73',
        'support': '6da278eba98643a33fd883ddff2591f54e3135047214c3be1706a942e2d10269',
    },
}


def _cases():
    """(name, kwargs of compute_footholds) for a fixed, seeded set of crawl inputs."""
    rng = np.random.default_rng(20261128)
    base = GaitParams()
    variants = [base, replace(base, correction_hips='actual'),
                replace(base, foothold_correction=False), replace(base, replan_window=2),
                replace(base, correction_threshold=0.0)]
    twists = [(0.0, 0.0, 0.0), (0.15, 0.0, 0.0), (0.0, 0.1, 0.0), (0.1, 0.0, 0.2),
              (0.2, 0.1, 0.25), (0.5, -0.3, -1.0), (-0.1, 0.05, 0.1)]
    nominal = np.asarray(base.hip_offsets) + np.asarray(base.stance_offsets)
    for i, params in enumerate(variants):
        for j, twist in enumerate(twists):
            for next_leg in range(4):
                yaw = float(rng.uniform(-math.pi, math.pi))
                base_xy = rng.uniform(-2.0, 2.0, 2)
                c, s = math.cos(yaw), math.sin(yaw)
                rot = np.array([[c, -s], [s, c]])
                feet = np.column_stack([base_xy + nominal @ rot.T + rng.normal(0, 0.05, (4, 2)),
                                        rng.uniform(0.0, 0.05, 4)])
                hips = np.column_stack([base_xy + np.asarray(base.hip_offsets) @ rot.T
                                        + rng.normal(0, 0.03, (4, 2)), np.full(4, 0.58)])
                kwargs = dict(velocity_set_point=twist, initial_feet=feet,
                              base_position=np.array([*base_xy, 0.58]), base_yaw=yaw,
                              hips=hips if (i + j + next_leg) % 2 else None,
                              next_leg=next_leg, start_time=round(rng.uniform(0, 50), 3),
                              params=params)
                k = (i * 7 + j) * 4 + next_leg
                if k % 3 == 1:
                    kwargs['delay'] = 1.0
                if k % 4 == 2:
                    kwargs['stride_correction'] = rng.normal(0, 0.02, 2)
                    kwargs['stride_time_scale'] = float(rng.uniform(0.9, 1.1))
                if k % 5 == 3:
                    kwargs['trend_shift'] = rng.normal(0, 0.04, 2)
                if k % 7 == 4:
                    kwargs['n'] = 3
                if k % 6 == 5 and any(twist):
                    old = np.array([twist] * 4, dtype=float)
                    old[next_leg] = (0.05, 0.0, 0.0) if next_leg % 2 else (0.0, 0.0, 0.0)
                    kwargs['placed_twists'] = old
                    kwargs['placed_until'] = np.full(4, kwargs['start_time'] - 0.75)
                    kwargs['placed_poses'] = np.column_stack([
                        np.tile(base_xy - 0.05, (4, 1)), np.full(4, yaw)])
                yield f'{i}-{j}-{next_leg}', kwargs


def _digests() -> dict[str, str]:
    """The three digests over every case."""
    h = {key: hashlib.sha256() for key in ('footholds', 'phases', 'support')}
    for name, kwargs in _cases():
        plan = compute_footholds(**kwargs)
        h['footholds'].update(name.encode())
        h['footholds'].update(np.float64([plan.start_time, plan.initial_yaw]).tobytes())
        h['footholds'].update(plan.initial_feet.tobytes())
        for st in plan.steps:
            h['footholds'].update(np.float64([st.leg, st.liftoff_time, st.touchdown_time,
                                              *st.target, st.step_height, st.haptic, st.replan,
                                              st.yaw]).tobytes())
        for t0, t1, feet, down in stance_phases(plan):
            h['phases'].update(np.float64([t0, t1]).tobytes() + feet.tobytes()
                               + down.tobytes())
        sched = support_schedule(plan, plan.start_time, 0.04, 200, 0.02, centres=True)
        for arr in (sched.A, sched.b, sched.active, sched.n_feet, sched.degenerate,
                    sched.centres, sched.stance_centres, sched.yaws):
            h['support'].update(np.ascontiguousarray(arr).tobytes())
    return {key: value.hexdigest() for key, value in h.items()}


def test_crawl_footholds_phases_and_support_are_bit_identical_to_before():
    kernels = os.environ.get('OPENBLAS_CORETYPE')
    assert kernels in EXPECTED, (f'OPENBLAS_CORETYPE={kernels}: run the tests from '
                                 f'scripts/env.sh, which sets one of {sorted(EXPECTED)}')
    assert _digests() == EXPECTED[kernels]


if __name__ == '__main__':
    for key, value in _digests().items():
        print(f'    {key!r}: {value!r},')
