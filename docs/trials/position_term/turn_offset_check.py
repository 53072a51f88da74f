"""One-off check of stop 44, kept as the record of a figure in docs/gait.md ("Switched on, then
off again"); not part of the stack. The loop of replan_ros.tools.planner_loop.walk (HyQ,
realistic parameters), but with the footholds laid out about a base at the CoM minus the
turned offset (DX, DY) m, turning in place at 0.2 rad/s; prints the base's mean body velocity
over 18-30 s. Usage (scripts/env.sh sourced): python turn_offset_check.py W_P DX DY"""
import sys
from dataclasses import replace
import numpy as np
from replan_core.gait import compute_footholds
from replan_core.mpc import LipMpc
from replan_core.robot_file import robot_facts
from replan_core.robot_model import RobotModel
from replan_core.support import implied_velocity
from replan_ros.launch.param_files import check_run_files, profile_file, robot_parameters
from replan_ros.params.convert import gait_params, mpc_settings
from replan_ros.tools.planner_loop import project_root

w_p = float(sys.argv[1]); d = np.array([float(sys.argv[2]), float(sys.argv[3])])
config = project_root() / 'config'
pp = profile_file(config, 'realistic'); layer = robot_parameters(config, 'hyq', pp)
run = check_run_files(config, [pp, layer.derived, layer.overrides]).values
mv = dict(run['mpc'], position_weight=w_p, position_sway=0.5 if w_p else 0.0)
spec = layer.spec; model = RobotModel(str(spec.urdf), spec.joints, spec.feet)
gait = replace(gait_params(run['gait']), hip_offsets=tuple((float(x), float(y)) for x, y in model.hip_offsets[:, :2]))
mpc = LipMpc(mpc_settings(mv)); facts = robot_facts(spec)
feet = np.column_stack([np.asarray(facts.feet_xy, float), np.zeros(4)])
R = lambda y: np.array([[np.cos(y), -np.sin(y)], [np.sin(y), np.cos(y)]])
def sp(t): return np.array([0.0, 0.0, 0.2]) if t >= 0.5 else np.zeros(3)
t, yaw = 0.0, 0.0
com = np.array([d[0], d[1], float(mv['com_height'])]); vel = np.zeros(3); acc = np.zeros(3)
def base_of(com, yaw):
    b = com.copy(); b[:2] = com[:2] - R(yaw) @ d; return b
plan = compute_footholds(sp(t), feet, base_of(com, yaw), yaw, None, gait.sequence[0], t, gait, delay=float(run['gait']['start_delay']))
log = []
while t < 30.0:
    res = mpc.solve(t, com, vel, acc, plan, v_ref=implied_velocity(plan))
    first = plan.steps[0]; t = first.touchdown_time
    com, vel, acc = res.plan.sample(t)
    feet = feet.copy(); feet[first.leg] = first.target; yaw = float(first.yaw)
    log.append((t, base_of(com, yaw)[:2].copy(), yaw))
    nxt = gait.sequence[(gait.sequence.index(first.leg) + 1) % 4]
    plan = compute_footholds(sp(t), feet, base_of(com, yaw), yaw, None, nxt, t, gait)
# base velocity in body frame over the last 12 s: integrate per step
sel = [e for e in log if e[0] > 18.0]
v = []
for (t0, p0, y0), (t1, p1, y1) in zip(sel, sel[1:]):
    dp = R(0.5 * (y0 + y1)).T @ (p1 - p0); v.append(dp / (t1 - t0))
print(f'w_p {w_p:g} d {d}: base body velocity mean (cm/s)', (np.mean(v, axis=0) * 100).round(2))
