"""State estimator of the "realistic robot": base pose/twist and foot contacts from IMU + joints.

No ground truth: every control tick (250 Hz) the controller calls ``StateEstimator.update`` with
one IMU sample and the joint states (encoder positions/velocities and the measured joint
torques), and gets the estimated ``BaseState`` and ``ContactState``. Three parts, as on HyQ and
Mini Cheetah:

- contact forces from joint torques and the model (HyQ had no foot sensors): the leg rows of
  the dynamics ``M vdot + h = tau + J^T f`` give the ground reaction force ``f`` on each foot.
  A generalized-momentum observer (De Luca and Mattone, ICRA 2005) estimates ``J^T f`` without
  accelerations: with ``p = (M v)_leg``, ``r = K (p - p(0) - int(tau - h + Mdot v + r) dt)``
  follows it as a first-order lag of time constant 1 / K. Its static limit (K = 0 in the
  parameters) drops ``M vdot``, which makes a swinging leg show a force that grows with the
  leg's mass and acceleration (up to 59 N on ANYmal C's free feet against 15 N with the
  observer). The force's world-z component, debounced like the simulator's contact sensing,
  gives the contact flags and the haptic touchdown/lift-off edges;
- attitude: gyro integration with a slow (Mahony) correction of roll and pitch towards the
  accelerometer's gravity direction and a slowly estimated gyro bias; yaw is not observable and
  drifts with the uncorrected gyro bias, as on a real robot;
- position and velocity: a linear Kalman filter on ``[p_base, v_base, p_foot x 4]`` (world),
  driven by the accelerometer and corrected by leg kinematics (Bloesch et al., RSS 2012; Bledt
  et al., IROS 2018): relative foot positions for every foot, base velocity from stance legs.

The kinematics are computed once per tick with pinocchio at the base pose
``(0, estimated orientation)``: foot positions and Jacobians then come out in world axes relative
to the base origin, and ``nonLinearEffects`` sees the right gravity direction.
"""

from __future__ import annotations

import math
import operator

import numpy as np
import pinocchio as pin
from scipy.linalg import lapack

from replan_core.common import rotations
from replan_core.common.types import GRAVITY, LEGS, BaseState, ContactState, ImuReading, JointState
from replan_core.estimation.settings import EstimatorParams
from replan_core.robot.model import RobotModel, unit_quaternion_matrix

N_LEGS = len(LEGS)
N_STATE = 6 + 3 * N_LEGS        # p_base, v_base, p_foot x 4
# Relative foot positions (12) and the base velocity (3): the four legs' velocity measurements
# share one H row block and have independent noises, so their weighted mean is an exactly
# equivalent single measurement (a 15- instead of a 24-row update).
N_MEAS = 3 * N_LEGS + 3
_G_WORLD = np.array([0.0, 0.0, -GRAVITY])   # m/s^2


class StateEstimator:
    """Base state and foot contacts from ``ImuReading`` + ``JointState``, one call per tick.

    ``rejected_samples`` counts the ticks with a non-finite IMU or joint sample (the estimate
    then only predicts); ``initialized`` is False until a valid joint sample arrived.
    ``prepare_next`` (optional, between two updates) does the next update's covariance work
    ahead; ``prepared_used`` counts the updates that used it.
    """

    def __init__(self, model: RobotModel, params: EstimatorParams, dt: float = 0.004,
                 initial_xy: tuple[float, float] | np.ndarray = (0.0, 0.0),
                 initial_yaw: float = 0.0) -> None:
        """dt: s, nominal control period; initial_xy: m, world x, y of base_link at spawn;
        initial_yaw: rad (yaw is not observable: it is taken as given)."""
        self.params = params
        p = self.params
        initial_xy = np.asarray(initial_xy, dtype=float)
        if initial_xy.shape != (2,) or not np.all(np.isfinite(initial_xy)):
            raise ValueError(f'initial_xy must be 2 finite numbers, got {initial_xy!r}')
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f'dt must be a positive time step (s), got {dt!r}')
        if not math.isfinite(initial_yaw):
            raise ValueError('initial_yaw must be finite')
        if not (math.isfinite(p.contact_observer_gain) and 0.0 <= p.contact_observer_gain * dt
                < 1.0):
            raise ValueError('contact_observer_gain (1/s) must be >= 0 and below 1 / dt, got '
                             f'{p.contact_observer_gain!r}')
        if p.contact_debounce_ticks < 1:
            raise ValueError('contact_debounce_ticks must be at least 1')
        if not 0.0 <= p.contact_release_threshold <= p.contact_force_threshold:
            raise ValueError('contact_release_threshold must be within [0, '
                             'contact_force_threshold]')
        if len(model.foot_frame_ids) != N_LEGS or model.leg_v_index.shape != (N_LEGS, 3):
            raise ValueError('the robot model must have 4 legs of 3 joints')
        self.model = model
        self.dt = float(dt)
        self._initial_xy = initial_xy
        self._initial_yaw = float(initial_yaw)
        self._pin_model = model.model
        self._pin_data = model.model.createData()    # ours: the controller owns model.data
        self._q = pin.neutral(model.model)           # base position stays at 0 (see module doc)
        self._v = np.zeros(model.model.nv)
        self._q_index = model.q_index
        self._v_index = model.v_index
        self._model_leg_v = np.asarray(model.leg_v_index, dtype=int)   # (4, 3) v columns
        # Fancy index picking each leg's 3x3 block out of the (4, 3, nv) foot Jacobians.
        self._leg_pick = (np.arange(N_LEGS)[:, None, None], np.arange(3)[None, :, None],
                          self._model_leg_v[:, None, :])
        self._feet = tuple(model.foot_frame_ids)
        self._damping2 = p.jacobian_damping ** 2

        # Constant Kalman matrices: the measurement model does not depend on the state.
        self._H = np.zeros((N_MEAS, N_STATE))
        for i in range(N_LEGS):
            rows, foot = slice(3 * i, 3 * i + 3), slice(6 + 3 * i, 9 + 3 * i)
            self._H[rows, 0:3] = -np.eye(3)
            self._H[rows, foot] = np.eye(3)
        self._H[12:15, 3:6] = np.eye(3)
        self._H_t = np.ascontiguousarray(self._H.T)
        self._eye = np.eye(N_STATE)
        self._eye3_damped = self._damping2 * np.eye(3)
        radius = p.foot_radius
        self._roll_map = np.array([[0.0, -radius, 0.0], [radius, 0.0, 0.0], [0.0, 0.0, 0.0]])
        self._tau_full = np.zeros(model.model.nv)
        self._jac_qd = np.zeros((N_LEGS, 3))     # m/s, world axes, foot velocity from joints
        self._roll_velocity = np.zeros((N_LEGS, 3))   # m/s, world, foot centre rolling
        self._z = np.zeros(N_MEAS)
        self._r_diag = np.zeros(N_MEAS)
        base_q = np.zeros(6)
        base_q[0:3] = p.base_position_noise ** 2 * dt
        base_q[3:6] = p.accel_noise ** 2 * dt
        self._q_diag = np.zeros(N_STATE)
        self._q_diag[:6] = base_q              # the feet's entries: per stance set, below
        self._q_diags: dict[bytes, np.ndarray] = {}
        self._q_stance3 = np.full((1, 3), p.foot_stance_noise ** 2 * dt)
        self._q_swing3 = np.full((1, 3), p.foot_swing_noise ** 2 * dt)
        self._r_diag[:12] = p.foot_position_noise ** 2      # constant; [12:] set per tick
        self._w_stance_vel = 1.0 / p.foot_velocity_noise ** 2
        self._w_swing_vel = 1.0 / p.swing_velocity_noise ** 2

        # Attitude filter state.
        self._quat = np.array([0.0, 0.0, 0.0, 1.0])  # x, y, z, w: base to world
        self._rot = np.eye(3)
        self.gyro_bias = np.zeros(3)                 # rad/s, estimated, base axes
        self._last_gyro = np.zeros(3)                # rad/s, last finite sample
        self._last_accel = np.array([0.0, 0.0, GRAVITY])   # m/s^2, last finite sample
        self._attitude_ready = False

        # Kalman filter state.
        self._x = np.zeros(N_STATE)
        self._x[0:2] = initial_xy
        self._P = np.eye(N_STATE)

        # Contact estimation state.
        self._force = np.zeros((N_LEGS, 3))          # N, world, last estimate
        # Momentum observer: the legs' rows of M (12, nv) of the last tick, the integral
        # p(0) + int(...) dt (12) and the residual r ~ J^T f (12, N m); None: start over.
        self._leg_rows = self._model_leg_v.reshape(-1)
        # The legs' rows of the symmetric M read from crba's upper triangle: entry (i, j) at
        # (min, max); one fancy index instead of two triu, a transpose and a sum per tick.
        columns = np.arange(self._pin_model.nv)[None, :]
        self._m_rows_index = (np.minimum(self._leg_rows[:, None], columns),
                              np.maximum(self._leg_rows[:, None], columns))
        self._observer: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._foot_rel = np.zeros((N_LEGS, 3))       # m, world axes, foot - base (kinematics)
        self._contact = np.zeros(N_LEGS, dtype=bool)
        self._raw = np.zeros(N_LEGS, dtype=bool)
        self._pending = np.zeros(N_LEGS, dtype=int)
        self._touchdown = np.zeros(N_LEGS, dtype=bool)
        self._liftoff = np.zeros(N_LEGS, dtype=bool)

        self.initialized = False
        self.rejected_samples = 0                   # ticks with a non-finite input
        self.last_rejection = ''                    # what the last rejected tick lacked
        self._last_stamp: float | None = None
        self._last_omega: np.ndarray | None = None   # rad/s, base axes, of the last result
        # The covariance step prepared for the next update (prepare_next): (stance flags as
        # bytes, the stamp s it is for, gain K, covariance after it).
        self._next_step: tuple | None = None
        self.prepared_used = 0                      # updates that used a prepared step
        self._swinging = np.zeros(N_LEGS, dtype=bool)   # the legs the controller swings

    # ------------------------------------------------------------------ public API
    @property
    def covariance(self) -> np.ndarray:
        """(18, 18) Kalman covariance of [p_base, v_base, p_foot x 4] (m, m/s), a copy."""
        return self._P.copy()

    @property
    def foot_states(self) -> np.ndarray:
        """(4, 3) m, world: the filter's foot positions (anchors of stance legs), a copy."""
        return self._x[6:].reshape(N_LEGS, 3).copy()

    def restart(self) -> None:
        """Start the position filter over at the next update, as at spawn: the robot at rest
        on its stance feet, those on the plane z = 0, at the current x, y estimate. The attitude
        (an IMU filter of its own) is kept. For a robot that stood up from sitting, whose feet
        carried nothing while the legs moved, so that their anchors and the base drifted."""
        if self.initialized and np.all(np.isfinite(self._x[0:2])):
            self._initial_xy = self._x[0:2].copy()
        self.initialized = False

    def prepare_next(self, next_stamp: float) -> bool:
        """Do the covariance work of the update stamped ``next_stamp`` (s) now: the Kalman
        prediction and gain of the covariance depend only on the feet in stance and the time
        step, not on the measurements. Prepared for the stance of now; that update uses it if
        its stamp is ``next_stamp``, the stance still holds and no foot touches down (the same
        operations on the same numbers, so bit for bit the result it would have computed),
        else it computes as usual. For a caller with idle time between two updates (the
        controller, after its command: the covariance work then leaves the tick's critical
        path). Returns whether a step was prepared."""
        self._next_step = None
        dt = next_stamp - self._last_stamp if self._last_stamp is not None else 0.0
        if not (self.initialized and 0.0 < dt <= 25.0 * self.dt):
            return False
        stance = self._stance_for_filter()
        covariance = self._P.copy()
        self._predict_covariance(covariance, dt, stance)
        gain = self._correct_covariance(covariance,
                                        float(self._velocity_weights(stance).sum()))
        self._next_step = (stance.tobytes(), next_stamp, gain, covariance)
        return True

    def update(self, imu: ImuReading, joints: JointState,
               swinging: np.ndarray | None = None) -> tuple[BaseState, ContactState]:
        """Fuse one IMU sample and the joint states of the same tick; never raises on bad data.

        ``swinging`` (4,) bool: the legs the controller swings (lifted off by the touchdown
        rule, not yet down); none of them anchors the filter, whatever force it shows. None:
        not known (every leg judged by its force alone).
        A repeated stamp returns the previous result unchanged (the lock-step republishes).
        """
        stamp = float(imu.stamp)
        if self._last_omega is not None and stamp == self._last_stamp:
            # The state is as the last update left it: the same result, in new arrays.
            return self._result(stamp, self._last_omega)
        self._swinging = (np.zeros(N_LEGS, dtype=bool) if swinging is None
                          else np.array(swinging, dtype=bool).reshape(N_LEGS))
        prepared, self._next_step = self._next_step, None     # made from the state of now only
        dt = self.dt
        if self._last_stamp is not None and math.isfinite(stamp):
            elapsed = stamp - self._last_stamp
            if 0.0 < elapsed <= 25.0 * self.dt:      # a missed tick: predict over it
                dt = elapsed

        gyro, accel = _vector(imu.angular_velocity, 3), _vector(imu.linear_acceleration, 3)
        imu_ok = gyro is not None and accel is not None
        q_meas = _vector(joints.position, 12)
        qd_meas = _vector(joints.velocity, 12)
        tau_meas = _vector(joints.effort, 12)
        joints_ok = q_meas is not None and qd_meas is not None and tau_meas is not None
        if not (imu_ok and joints_ok):
            self.rejected_samples += 1
            self.last_rejection = 'imu' if not imu_ok else 'joints'
            if not (imu_ok or joints_ok):
                self.last_rejection = 'imu and joints'
        if not imu_ok:
            gyro, accel = self._last_gyro, self._last_accel   # hold: predict only
        else:
            self._last_gyro, self._last_accel = gyro, accel

        saved = self._snapshot()
        step = None                                 # the prepared step this update uses
        try:
            omega_body = self._update_attitude(gyro, accel, dt, correct=imu_ok)
            if joints_ok:
                self._kinematics_and_contacts(q_meas, qd_meas, tau_meas, omega_body, dt)
                # A prepared covariance step holds for its stamp (so the same time step) and
                # the same stance, without a touchdown (its foot reset changes the covariance
                # first).
                if (prepared is not None and self.initialized and stamp == prepared[1]
                        and not self._touchdown.any()
                        and self._stance_for_filter().tobytes() == prepared[0]):
                    step = prepared
            else:
                self._touchdown = np.zeros(N_LEGS, dtype=bool)
                self._liftoff = np.zeros(N_LEGS, dtype=bool)
                self._observer = None     # its integral cannot span a gap: start over
            if not self.initialized:
                if joints_ok:
                    self._initialize_filter()
            else:
                self._predict(accel, dt, step)
                if joints_ok:
                    self._correct(qd_meas, omega_body, step)
            # One sum: any NaN or inf in the state or the outputs makes it non-finite.
            finite = math.isfinite(float(
                self._x.sum() + self._P.sum() + self._quat.sum() + self.gyro_bias.sum()
                + self._force.sum() + self._foot_rel.sum()))
        except (np.linalg.LinAlgError, ValueError, FloatingPointError, RuntimeError):
            finite = False
        if step is not None:
            self.prepared_used += 1
        if not finite:                              # keep the previous estimate, report it
            self._restore(saved)
            self.rejected_samples += 1
            self.last_rejection = 'numerical'
            omega_body = self._last_gyro - self.gyro_bias
            if not np.all(np.isfinite(omega_body)):
                omega_body = np.zeros(3)

        result = self._result(stamp if math.isfinite(stamp) else (self._last_stamp or 0.0),
                              omega_body)
        self._last_stamp = result[0].stamp
        # What a repeated stamp needs to build the result again (no copy kept of it: the
        # caller owns the arrays returned).
        self._last_omega = omega_body
        return result

    # Arrays an update replaces by new ones (kept by reference) and ones it changes in place.
    _REPLACED = ('_quat', '_rot', 'gyro_bias', '_force', '_foot_rel', '_jac_qd',
                 '_roll_velocity', '_contact', '_observer',
                 '_raw', '_pending', '_touchdown', '_liftoff')
    _IN_PLACE = ('_x', '_P')

    # One C-level call fetching every _REPLACED attribute (a generator of getattr costs ~3 us).
    _get_replaced = operator.attrgetter(*_REPLACED)

    def _snapshot(self) -> tuple:
        return (self._get_replaced(self),
                tuple(getattr(self, name).copy() for name in self._IN_PLACE),
                self.initialized, self._attitude_ready)

    def _restore(self, saved: tuple) -> None:
        replaced, copied, self.initialized, self._attitude_ready = saved
        for name, value in zip(self._REPLACED + self._IN_PLACE, replaced + copied, strict=True):
            setattr(self, name, value)
        self._touchdown = np.zeros(N_LEGS, dtype=bool)   # an edge is reported once only
        self._liftoff = np.zeros(N_LEGS, dtype=bool)

    # ------------------------------------------------------------------ attitude
    def _update_attitude(self, gyro: np.ndarray, accel: np.ndarray, dt: float,
                         correct: bool) -> np.ndarray:
        """Propagate the orientation; returns the bias-corrected body rate (rad/s)."""
        p = self.params
        if not self._attitude_ready:
            self._quat = _level_quaternion(accel, self._initial_yaw)
            self._rot = rotations.quaternion_to_matrix(self._quat)
            self._attitude_ready = True
            return gyro - self.gyro_bias
        omega = gyro - self.gyro_bias
        # Plain floats: on 3-vectors numpy's call overhead costs more than the arithmetic.
        rx, ry, rz = omega.tolist()
        ax, ay, az = accel.tolist()
        norm = math.sqrt(ax * ax + ay * ay + az * az)
        # Only a specific force close to g points along gravity: impacts and pushes would tilt
        # the estimate, the gyro alone is better over them.
        if correct and abs(norm - GRAVITY) < p.accel_gate:
            ux, uy, uz = self._rot[2].tolist()   # R^T e_z: world up in base axes
            ax, ay, az = ax / norm, ay / norm, az / norm
            # accel x up: orthogonal to the vertical, it corrects roll and pitch, never yaw.
            ex, ey, ez = ay * uz - az * uy, az * ux - ax * uz, ax * uy - ay * ux
            kp, ki, limit = p.attitude_gain, p.gyro_bias_gain * dt, p.gyro_bias_limit
            rx, ry, rz = rx + kp * ex, ry + kp * ey, rz + kp * ez
            bx, by, bz = self.gyro_bias
            self.gyro_bias = np.array([min(max(bx - ki * ex, -limit), limit),
                                       min(max(by - ki * ey, -limit), limit),
                                       min(max(bz - ki * ez, -limit), limit)])
        rate = math.sqrt(rx * rx + ry * ry + rz * rz)
        if rate * dt > 1e-12:
            scale = math.sin(0.5 * rate * dt) / rate      # exp of the rotation vector rate * dt
            dx, dy, dz = rx * scale, ry * scale, rz * scale
            dw = math.cos(0.5 * rate * dt)
            # quat * delta (rotations.multiply), normalised, and its matrix, on floats: the
            # numpy versions cost ~15 us per tick in call overhead on these 4-vectors.
            qx, qy, qz, qw = self._quat.tolist()
            x = qw * dx + qx * dw + qy * dz - qz * dy
            y = qw * dy - qx * dz + qy * dw + qz * dx
            z = qw * dz + qx * dy - qy * dx + qz * dw
            w = qw * dw - qx * dx - qy * dy - qz * dz
            norm = math.sqrt(x * x + y * y + z * z + w * w)
            x, y, z, w = x / norm, y / norm, z / norm, w / norm
            self._quat = np.array((x, y, z, w))
            self._rot = unit_quaternion_matrix(x, y, z, w)
        return omega

    # ------------------------------------------------------------------ kinematics, contacts
    def _kinematics_and_contacts(self, q_meas: np.ndarray, qd_meas: np.ndarray,
                                 tau_meas: np.ndarray, omega_body: np.ndarray,
                                 dt: float) -> None:
        """One pinocchio pass: foot positions, Jacobians, forces, debounced contact flags."""
        model, data = self._pin_model, self._pin_data
        q, v = self._q, self._v
        q[3:7] = self._quat
        q[self._q_index] = q_meas
        # Base twist in the LOCAL frame (pinocchio's free-flyer convention) for the Coriolis
        # terms of h; the base position is irrelevant to h.
        v[0:3] = self._rot.T @ self._x[3:6]
        v[3:6] = omega_body
        v[self._v_index] = qd_meas
        pin.computeJointJacobians(model, data, q)
        nle = pin.nonLinearEffects(model, data, q, v)
        pin.updateFramePlacements(model, data)
        oMf = data.oMf
        self._foot_rel = np.array([oMf[f].translation for f in self._feet])
        lwa = pin.LOCAL_WORLD_ALIGNED
        # (4, 6, nv): the four foot Jacobians, world axes, as one array so that the products
        # below are one batched call each instead of one per foot.
        jac6 = np.array([pin.getFrameJacobian(model, data, f, lwa) for f in self._feet])
        # The foot is a sphere that rolls on the ground: its centre (the foot frame) moves by
        # omega_foot x (radius e_z) while the sole does not slip. Ignored, the shank's
        # rotation through a stance made the base look 3 % slower than it walked
        # (config/scenarios/long_walk.yaml: 0.196 m of drift over 5.8 m).
        # omega_feet @ _roll_map = (r w_y, -r w_x, 0) exactly (the other terms are zeros).
        self._roll_velocity = (jac6[:, 3:] @ v) @ self._roll_map       # (4, 3) m/s, world
        # A foot's Jacobian is zero on the other legs' joints: one product gives every J_i qd_i.
        jac_lin = jac6[:, :3]
        self._jac_qd = jac_lin[..., 6:] @ v[6:]                        # (4, 3)
        jac = jac_lin[self._leg_pick]                                  # (4, 3, 3) J_leg
        tau_full = self._tau_full
        tau_full[self._v_index] = tau_meas
        rhs = self._leg_residual(q, v, nle - tau_full, dt).reshape(N_LEGS, 3, 1)  # J^T f
        # f = J^-T (J^T f), damped: J (J^T J + lambda^2 I)^-1 keeps a stretched leg finite.
        jac_t = jac.transpose(0, 2, 1)
        self._force = (jac @ np.linalg.solve(jac_t @ jac + self._eye3_damped, rhs))[..., 0]
        p = self.params
        # Flags of 4 feet on Python bools and ints: a dozen numpy calls on 4-element arrays
        # cost more than the logic (the comparisons are the same, so the same flags).
        release, threshold = p.contact_release_threshold, p.contact_force_threshold
        contact = self._contact.tolist()
        raw = [fz > release if was else fz > threshold
               for fz, was in zip(self._force[:, 2].tolist(), contact, strict=True)]
        self._raw = np.array(raw)
        if not self.initialized:
            # Spawned standing: no edge. Before the first command no torque acts and no foot
            # shows a force; the robot is on its feet all the same.
            self._contact = self._raw.copy() if any(raw) else np.ones(N_LEGS, dtype=bool)
            self._pending = np.zeros(N_LEGS, dtype=int)
            self._touchdown = np.zeros(N_LEGS, dtype=bool)
            self._liftoff = np.zeros(N_LEGS, dtype=bool)
            return
        # The simulator's debounce (SimWorld._update_contact_flags), on the estimated force: a
        # flag flips after contact_debounce_ticks (>= 1) ticks in a row of the other raw value.
        pending = self._pending.tolist()
        touchdown = [False] * N_LEGS
        liftoff = [False] * N_LEGS
        for i in range(N_LEGS):
            if raw[i] == contact[i]:
                pending[i] = 0
                continue
            pending[i] += 1
            if pending[i] >= p.contact_debounce_ticks:
                touchdown[i], liftoff[i] = raw[i], not raw[i]
                contact[i] = raw[i]
                pending[i] = 0
        self._pending = np.array(pending, dtype=int)
        self._touchdown = np.array(touchdown)
        self._liftoff = np.array(liftoff)
        self._contact = np.array(contact)

    def _leg_residual(self, q: np.ndarray, v: np.ndarray, h_minus_tau: np.ndarray,
                      dt: float) -> np.ndarray:
        """(12,) N m, J^T f of the four legs' joints: the momentum observer's residual r, or
        with gain 0 the static (h - tau)_leg. The observer starts from the static value."""
        rows = self._leg_rows
        gain = self.params.contact_observer_gain
        static = h_minus_tau[rows]
        if gain <= 0.0:
            return static
        pin.crba(self._pin_model, self._pin_data, q)       # upper triangle of M
        upper = self._pin_data.M
        # (12, nv) kg m^2, kg m. ``+ 0.0`` as the triangles' sum had: the same bits (a -0.0
        # becomes +0.0 there too).
        m_rows = upper[self._m_rows_index] + 0.0
        momentum = m_rows @ v                                      # p_leg, N m s
        # One step moves r by gain * dt of its error: from 1 on (a gap of several missed
        # ticks) it would overshoot, so the observer starts over from the static value.
        if self._observer is None or not self.initialized or gain * dt >= 1.0:
            residual = static
            integral = momentum - residual / gain
        else:
            m_last, integral, residual = self._observer
            # d/dt (M v)_leg = tau - h + Mdot v + J^T f (leg rows); Mdot v by the difference of
            # M over the tick, so no Coriolis matrix and no acceleration is needed.
            integral = integral + ((m_rows - m_last) @ v - static * dt + residual * dt)
            residual = gain * (momentum - integral)
        self._observer = (m_rows, integral, residual)
        return residual

    # ------------------------------------------------------------------ Kalman filter
    def _initialize_filter(self) -> None:
        """Base over the stance feet, those resting on z = 0 (the spawn); at rest."""
        p = self.params
        stance = self._contact
        height = float(np.mean(p.foot_radius - self._foot_rel[stance, 2]))
        x = self._x
        x[0:2] = self._initial_xy
        x[2] = height
        x[3:6] = 0.0
        x[6:] = (x[0:3] + self._foot_rel).ravel()
        diag = np.concatenate([np.full(3, p.initial_position_noise ** 2),
                               np.full(3, p.initial_velocity_noise ** 2),
                               np.full(3 * N_LEGS, p.foot_position_noise ** 2)])
        self._P = np.diag(diag)
        # The feet are known through the base: correlate them so the filter does not trust
        # the initial feet more than the initial base.
        for i in range(N_LEGS):
            self._reset_foot(i)
        self.initialized = True

    def _reset_foot(self, leg: int) -> None:
        """Foot state := base + kinematics, with the covariance that assignment implies."""
        sl = slice(6 + 3 * leg, 9 + 3 * leg)
        self._x[sl] = self._x[0:3] + self._foot_rel[leg]
        P = self._P
        P[sl, :] = P[0:3, :]
        P[:, sl] = P[:, 0:3]
        P[sl, sl] = P[0:3, 0:3] + np.eye(3) * self.params.foot_position_noise ** 2

    def _predict(self, accel: np.ndarray, dt: float, step: tuple | None = None) -> None:
        """Constant-acceleration step of the base with the IMU; feet random walks. With a
        prepared ``step`` the covariance is left to ``_correct``, which takes the step's."""
        ax, ay, az = (self._rot @ accel + _G_WORLD).tolist()
        x, P = self._x, self._P
        # The base's step on floats: the products and sums numpy's elementwise operations did,
        # one by one and in the same order (numpy fuses none), without six calls on 3-vectors.
        px, py, pz, vx, vy, vz = x[0:6].tolist()
        half = 0.5 * dt * dt
        x[0:6] = (px + (vx * dt + ax * half), py + (vy * dt + ay * half),
                  pz + (vz * dt + az * half), vx + ax * dt, vy + ay * dt, vz + az * dt)
        stance = self._stance_for_filter()
        x[6:] += (self._roll_velocity * (dt * stance[:, None])).ravel()   # rolling feet
        if step is None:
            self._predict_covariance(P, dt, stance)

    def _predict_covariance(self, P: np.ndarray, dt: float, stance: np.ndarray) -> None:
        """The prediction's covariance, in ``P``: F P F^T + Q for feet ``stance``."""
        # P := F P F^T with F = I + dt * (dp/dv): a row then a column operation.
        P[0:3, :] += dt * P[3:6, :]
        P[:, 0:3] += dt * P[:, 3:6]
        # The process noise's diagonal of a stance set: 16 sets at most, each built once.
        key = stance.tobytes()
        q_diag = self._q_diags.get(key)
        if q_diag is None:
            q_diag = self._q_diag.copy()
            # (4, 1) flags against (1, 3) noises: the feet's (4, 3) block at once.
            q_diag[6:].reshape(N_LEGS, 3)[:] = np.where(stance[:, None], self._q_stance3,
                                                        self._q_swing3)
            self._q_diags[key] = q_diag
        scale = dt / self.dt
        # The diagonal, as a view; a product by exactly 1.0 (the usual tick) changes no bit.
        P.ravel()[::N_STATE + 1] += q_diag if scale == 1.0 else q_diag * scale

    def _stance_for_filter(self) -> np.ndarray:
        # A foot whose force already fell under the threshold is free even before the
        # debounced flag falls: anchoring the base to a lifting foot drags it along. A foot
        # the controller swings is free whatever its force shows: in a trot, a lifted foot
        # whose estimated force stayed above the release threshold for a few ticks, taken as
        # one of the two anchors, dragged the base velocity by its swing (0.8 m/s in 40 ms
        # on ANYmal C), and that wrong velocity made the observer show forces on the swinging
        # feet (docs/realism.md, "position and velocity").
        return self._contact & self._raw & ~self._swinging

    def _correct(self, qd_meas: np.ndarray, omega_body: np.ndarray,
                 step: tuple | None = None) -> None:
        """Kinematic update: relative foot positions (all feet), base velocity (stance legs)."""
        if self._touchdown.any():
            for leg in np.flatnonzero(self._touchdown):
                self._reset_foot(int(leg))
        stance = self._stance_for_filter()
        wx, wy, wz = (self._rot @ omega_body).tolist()
        # Foot velocity = v_base + omega x r + J qd = 0 on the ground: r @ skew(w)^T = w x r.
        skew_t = np.array(((0.0, wz, -wy), (-wz, 0.0, wx), (wy, -wx, 0.0)))
        v_legs = self._roll_velocity - (self._jac_qd + self._foot_rel @ skew_t)   # (4, 3) m/s
        weight = self._velocity_weights(stance)
        weight_sum = float(weight.sum())
        z = self._z
        z[:12] = self._foot_rel.ravel()
        z[12:] = weight @ v_legs / weight_sum                       # information-weighted mean
        x = self._x
        innovation = z - self._H @ x
        if step is None:
            gain = self._correct_covariance(self._P, weight_sum)
        else:
            gain, self._P = step[2], step[3]
        x += gain @ innovation

    def _velocity_weights(self, stance: np.ndarray) -> np.ndarray:
        """(4,) weights (1 / noise^2, s^2/m^2) of the legs' base-velocity measurements: 1 /
        noise picked per leg (the divisions done once in __init__)."""
        return np.where(stance, self._w_stance_vel, self._w_swing_vel)

    def _correct_covariance(self, P: np.ndarray, weight_sum: float) -> np.ndarray:
        """The correction's covariance, in ``P``; returns the Kalman gain K (18, 15)."""
        r_diag = self._r_diag
        r_diag[12:] = 1.0 / weight_sum
        H = self._H
        PHt = P @ self._H_t
        S = H @ PHt
        S.ravel()[::N_MEAS + 1] += r_diag
        # S symmetric: K = P H^T S^-1 = (S^-1 H P)^T. LAPACK's dgesv straight (the LU solve
        # np.linalg.solve runs too, without its ~5 us of Python wrapping); PHt.T is
        # Fortran-ordered, so it is passed without a copy.
        _, _, gain_t, info = lapack.dgesv(S, PHt.T)
        if info != 0:
            raise np.linalg.LinAlgError(f'singular innovation covariance (dgesv info {info})')
        K = gain_t.T
        # Joseph form: stays symmetric positive definite even with the 1e6 ratio of noises.
        A = self._eye - K @ H
        P_new = A @ P @ A.T
        P_new += (K * r_diag) @ K.T
        # 0.5 (P_new + P_new^T) written into the state's own array (no new one per tick).
        np.add(P_new, P_new.T, out=P)
        P *= 0.5
        return K

    # ------------------------------------------------------------------ output
    def _result(self, stamp: float, omega_body: np.ndarray) -> tuple[BaseState, ContactState]:
        position = self._x[0:3].copy()
        base = BaseState(stamp=stamp, position=position, quaternion=self._quat.copy(),
                         linear_velocity=self._x[3:6].copy(),
                         angular_velocity=self._rot @ omega_body)
        contact = ContactState(stamp=stamp, foot_position=position + self._foot_rel,
                               force=self._force.copy(), contact=self._contact.copy(),
                               touchdown=self._touchdown.copy(), liftoff=self._liftoff.copy())
        return base, contact


def _vector(values, size: int) -> np.ndarray | None:
    """``values`` as a float array of ``size`` if it has that shape and is finite, else None."""
    try:
        array = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        return None
    # One sum: NaN or inf anywhere makes it non-finite (cheaper than isfinite().all()).
    if array.shape != (size,) or not math.isfinite(float(array.sum())):
        return None
    return array


def _level_quaternion(accel: np.ndarray, yaw: float) -> np.ndarray:
    """Orientation (x, y, z, w) with roll/pitch from a specific force at rest, and ``yaw``."""
    ax, ay, az = accel
    roll = math.atan2(ay, az)
    pitch = math.atan2(-ax, math.hypot(ay, az))
    half = [(math.sin(a / 2.0), math.cos(a / 2.0)) for a in (roll, pitch, yaw)]
    q_roll = (half[0][0], 0.0, 0.0, half[0][1])
    q_pitch = (0.0, half[1][0], 0.0, half[1][1])
    q_yaw = (0.0, 0.0, half[2][0], half[2][1])
    # ZYX: R = Rz(yaw) Ry(pitch) Rx(roll).
    return np.array(rotations.normalized(
        rotations.multiply(q_yaw, rotations.multiply(q_pitch, q_roll))))

