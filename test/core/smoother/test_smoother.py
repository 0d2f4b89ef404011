"""The RTS smoother of the closed-loop error-state filter (core.smoother.rts,
core.smoother.history) on a linear-Gaussian toy problem, against filterpy's open-loop Kalman filter
+ rts_smoother and against the batch solution of the whole trajectory; the history's rollbacks and
its chunks on disk.

The toy: position, velocity and a Gauss-Markov measurement bias; position measurements (two at
some steps, none at others), one step with extra noise and one where the bias restarts (the
engine's GNSS error states after a change of fix type). The closed-loop filter feeds every
update back into its nominal state and records through the engine's hooks, as the engine does.
"""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter, rts_smoother

from ins_fusion.core.smoother.history import SmootherHistory, Snapshot
from ins_fusion.core.smoother.rts import Smoothed, backward_step, smoother_gain

DT = 0.5
F = np.array([[1.0, DT, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, np.exp(-DT / 20.0)]])
Q = np.diag([0.01, 0.04, 2.0 * 0.3**2 / 20.0 * DT])
M_RESTART = np.diag([1.0, 1.0, 0.0])  # the bias restarts...
Q_RESTART = np.diag([0.0, 0.0, 0.5**2])  # ...at this variance
Q_NOISE = np.diag([0.3, 0.1, 0.0])
H = np.array([[1.0, 0.0, 1.0]])
R = np.array([[0.2**2]])
X0, P0 = np.array([0.0, 1.0, 0.0]), np.diag([1.0, 0.5, 0.3**2])
STEPS = 60
RESTART_STEP, NOISE_STEP = 25, 40


def _toy(seed: int) -> tuple[np.ndarray, dict[int, list[float]]]:
    """True states (STEPS + 1, 3) and measurements per step (none during an 'outage')."""
    rng = np.random.default_rng(seed)
    x = rng.multivariate_normal(X0, P0)
    truth, zs = [x], {}
    for k in range(1, STEPS + 1):
        x = F @ x + rng.multivariate_normal(np.zeros(3), Q)
        if k == RESTART_STEP:
            x = M_RESTART @ x + rng.multivariate_normal(np.zeros(3), Q_RESTART)
        if k == NOISE_STEP:
            x = x + rng.multivariate_normal(np.zeros(3), Q_NOISE)
        truth.append(x)
        if 12 <= k < 22:
            continue  # an outage
        count = 2 if k % 3 == 0 else 1
        zs[k] = [float(H[0] @ x) + rng.normal(0.0, 0.2) for _ in range(count)]
    return np.array(truth), zs


class _ClosedLoop:
    """The toy's closed-loop error-state filter, recorded through the engine's hooks."""

    def __init__(self, history_kwargs: dict | None = None) -> None:
        self.x, self.P, self.t = X0.copy(), P0.copy(), 0.0
        options = {"horizon_s": 1e9, **(history_kwargs or {})}
        self.history = SmootherHistory(3, np.arange(3), self._snapshot, **options)

    def _snapshot(self) -> Snapshot:
        return Snapshot(self.t, self.x.copy(), np.eye(3), True)

    def transition(self, k: int) -> None:
        rec = self.history
        self.t = float(k)
        before, self.x, self.P = self.P, F @ self.x, F @ self.P @ F.T + Q
        rec.on_transition(before, F, self.P)
        if k == RESTART_STEP:
            before = self.P
            self.x = M_RESTART @ self.x
            self.P = M_RESTART @ self.P @ M_RESTART.T + Q_RESTART
            rec.on_restart(before, self.P, range(2, 3))
        if k == NOISE_STEP:
            before, self.P = self.P, self.P + Q_NOISE
            rec.on_noise(before, self.P)

    def update(self, z: float) -> None:
        S = H @ self.P @ H.T + R
        K = self.P @ H.T @ np.linalg.inv(S)
        dx = (K @ (z - H @ self.x)).ravel()
        self.x = self.x + dx
        ikh = np.eye(3) - K @ H
        self.P = ikh @ self.P @ ikh.T + K @ R @ K.T
        self.history.on_correction(dx)

    def run(self, zs: dict[int, list[float]]) -> None:
        for k in range(1, STEPS + 1):
            self.transition(k)
            for z in zs.get(k, []):
                self.update(z)

    def smoothed(self) -> tuple[np.ndarray, np.ndarray]:
        """Smoothed states and covariances at steps 1..STEPS (the snapshot is the prior)."""
        self.history.finish(self.P)
        epochs, last_t = [], np.inf
        for epoch in self.history.backward():  # of several records at a step, the last holds it
            if epoch.t_s < last_t:
                epochs.append(epoch)
                last_t = epoch.t_s
        epochs.reverse()
        return (
            np.array([e.row + e.delta for e in epochs]),
            np.array([e.cov for e in epochs]),
        )


def _model(k: int) -> tuple[np.ndarray, np.ndarray]:
    """Transition into step k and its noise, the restart and the extra noise folded in."""
    if k == RESTART_STEP:
        return M_RESTART @ F, M_RESTART @ Q @ M_RESTART.T + Q_RESTART
    if k == NOISE_STEP:
        return F, Q + Q_NOISE
    return F, Q


def _filterpy(zs: dict[int, list[float]]) -> tuple[np.ndarray, np.ndarray]:
    """Open-loop Kalman filter (the restart and the extra noise folded into that step's F and
    Q) and filterpy's RTS smoother, at steps 1..STEPS."""
    kf = KalmanFilter(dim_x=3, dim_z=1)
    kf.x, kf.P = X0.copy(), P0.copy()
    xs, ps, fs, qs = [], [], [], []
    for k in range(1, STEPS + 1):
        f, q = _model(k)
        kf.predict(F=f, Q=q)
        for z in zs.get(k, []):
            kf.update(np.array([z]), R=R, H=H)
        xs.append(kf.x.copy())
        ps.append(kf.P.copy())
        fs.append(f)
        qs.append(q)
    # filterpy's Fs[k], Qs[k] lead from step k to step k + 1.
    fs, qs = [*fs[1:], F], [*qs[1:], Q]
    x_s, p_s, _, _ = rts_smoother(np.array(xs), np.array(ps), np.array(fs), np.array(qs))
    return x_s, p_s


def _batch(zs: dict[int, list[float]]) -> np.ndarray:
    """The conditional mean of all states 1..STEPS given all measurements, from the joint
    Gaussian of the whole trajectory (no recursion)."""
    n = 3 * (STEPS + 1)
    # x = A w with w = (x_0, w_1..w_N): each state is a linear function of the noises.
    A = np.zeros((n, n))
    cov_w = np.zeros((n, n))
    cov_w[:3, :3] = P0
    A[:3, :3] = np.eye(3)
    for k in range(1, STEPS + 1):
        f, q = _model(k)
        A[3 * k : 3 * k + 3] = f @ A[3 * k - 3 : 3 * k]
        A[3 * k : 3 * k + 3, 3 * k : 3 * k + 3] += np.eye(3)
        cov_w[3 * k : 3 * k + 3, 3 * k : 3 * k + 3] = q
    mean = A[:, :3] @ X0
    cov = A @ cov_w @ A.T
    rows, values = [], []
    for k, measured in zs.items():
        for z in measured:
            row = np.zeros(n)
            row[3 * k : 3 * k + 3] = H[0]
            rows.append(row)
            values.append(z)
    Hb = np.array(rows)
    S = Hb @ cov @ Hb.T + R[0, 0] * np.eye(len(rows))
    posterior = mean + cov @ Hb.T @ np.linalg.solve(S, np.array(values) - Hb @ mean)
    return posterior.reshape(STEPS + 1, 3)[1:]


@pytest.mark.parametrize("seed", [1, 2])
def test_closed_loop_smoother_equals_filterpy_rts_and_the_batch_solution(seed):
    truth, zs = _toy(seed)
    loop = _ClosedLoop()
    loop.run(zs)
    x_s, p_s = loop.smoothed()
    x_ref, p_ref = _filterpy(zs)
    np.testing.assert_allclose(x_s, x_ref, atol=1e-9)
    np.testing.assert_allclose(p_s, p_ref, atol=1e-9)
    np.testing.assert_allclose(x_s, _batch(zs), atol=1e-7)
    # The smoother helps where the filter coasted: inside the outage and before the restart.
    outage = slice(11, 21)
    forward_error = np.abs(_forward(zs)[outage, 0] - truth[1:][outage, 0]).max()
    assert np.abs(x_s[outage, 0] - truth[1:][outage, 0]).max() < forward_error


def _forward(zs: dict[int, list[float]]) -> np.ndarray:
    loop = _ClosedLoop()
    xs = []
    for k in range(1, STEPS + 1):
        loop.transition(k)
        for z in zs.get(k, []):
            loop.update(z)
        xs.append(loop.x.copy())
    return np.array(xs)


def test_a_rollback_leaves_the_records_of_the_final_timeline():
    _, zs = _toy(3)
    straight = _ClosedLoop()
    straight.run(zs)
    expected, _ = straight.smoothed()

    # Rollbacks reach 3 steps back; chunks of 7 records go to disk on the way.
    loop = _ClosedLoop({"chunk_records": 7, "horizon_s": 3.0})
    rec = loop.history
    for k in range(1, STEPS + 1):
        loop.transition(k)
        state = (loop.x.copy(), loop.P, loop.t)
        rec.on_checkpoint(loop.t)
        if k % 5 == 0:  # a superseded timeline: a wrong update and two more steps, undone
            loop.update(99.0)
            loop.transition(k + 1)
            loop.update(-5.0)
            loop.x, loop.P, loop.t = state
            rec.on_rollback(loop.t)
        for z in zs.get(k, []):
            loop.update(z)
    assert rec.records == STEPS + 2  # 60 steps, the restart and the noise
    assert rec.bytes_on_disk > 0
    smoothed, _ = loop.smoothed()
    np.testing.assert_allclose(smoothed, expected, atol=1e-12)
    rec.close()


def test_segments_do_not_share_information():
    _, zs = _toy(4)
    loop = _ClosedLoop()
    for k in range(1, STEPS + 1):
        loop.transition(k)
        if k == 30:
            loop.history.on_break(loop.P)
        for z in zs.get(k, []):
            loop.update(z)
    smoothed, cov = loop.smoothed()
    # Step 30 ended the first segment before its own update: the smoothed state there is the
    # forward posterior, whatever the later measurements say.
    first = _ClosedLoop()
    for k in range(1, 31):
        first.transition(k)
        if k < 30:
            for z in zs.get(k, []):
                first.update(z)
    np.testing.assert_allclose(smoothed[29], first.x, atol=1e-12)
    np.testing.assert_allclose(cov[29], first.P, atol=1e-12)


def test_the_gain_of_a_state_without_variance_is_zero():
    P_post = np.diag([1.0, 0.0])
    P_prior = np.diag([2.0, 0.0])  # singular: a state restarted at zero variance
    gain = smoother_gain(P_post, np.eye(2), P_prior)
    np.testing.assert_allclose(gain, np.diag([0.5, 0.0]))
    step = backward_step(
        Smoothed(np.array([1.0, 3.0]), P_prior), np.zeros(2), P_post, np.eye(2), P_prior
    )
    np.testing.assert_allclose(step.error, [0.5, 0.0])
