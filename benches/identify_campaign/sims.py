"""Simulators of the identification experiments, written independently of gmsfric.

Nothing here imports gmsfric: the campaign judges the package's identifiers on data it did not
make.  Three experiments:

* elasto-plastic (Maxwell-slip) blocks along a position record (pre-sliding);
* a mass with the static friction map (eq. 2), Karnopp stiction at zero velocity, under a
  sampled PID position loop following constant-velocity ramps (raw static-map runs);
* ``a / (s^2 + b s + c) e^{-s tau}`` with a zero-order-held input and a fractional delay, exact
  discretisation from matrix exponentials (open and closed loop).

The time-stepping loops use numba when it is installed (the ``bench`` extra) and run as plain
Python otherwise (same code, slower).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import expm
from scipy.signal import dlsim

try:  # numba only speeds the loops up; the results are the same without it
    from numba import njit
except ImportError:  # pragma: no cover
    def njit(*args, **kwargs):  # type: ignore[no-untyped-def]
        if args and callable(args[0]):
            return args[0]
        return lambda f: f


# --------------------------------------------------------------------------- pre-sliding

@njit(cache=True, nogil=True)  # nogil: reference fits run in two threads
def _blocks_loop(x: NDArray[np.float64], k: NDArray[np.float64], d: NDArray[np.float64], z0: NDArray[np.float64]) -> NDArray[np.float64]:
    n, nb = x.size, k.size
    z = z0.copy()
    out = np.empty(n)
    xp = x[0]
    for j in range(n):
        dx = x[j] - xp
        xp = x[j]
        f = 0.0
        for i in range(nb):
            zi = z[i] + dx
            # a block sticks (spring stretches with the motion) until its spring force reaches
            # w_i = k_i d_i, then slides with the spring held at d_i: the exact elasto-plastic map
            if zi > d[i]:
                zi = d[i]
            elif zi < -d[i]:
                zi = -d[i]
            z[i] = zi
            f += k[i] * zi
        out[j] = f
    return out


def maxwell_slip_force(x: NDArray[np.float64], k: NDArray[np.float64], w: NDArray[np.float64], z0: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """Friction force of elasto-plastic blocks (stiffness ``k`` N/m, break force ``w`` N) along
    the position ``x`` (m); ``z0`` the initial spring deflections (virgin: zeros).

    Exact for motion that is monotone between samples (the caller oversamples near reversals).
    """
    k = np.asarray(k, float)
    d = np.asarray(w, float) / k
    z = np.zeros_like(k) if z0 is None else np.asarray(z0, float)
    return _blocks_loop(np.ascontiguousarray(x, dtype=float), k, d, z)


def virgin_sine_position(t: NDArray[np.float64], amplitudes: list[float], freq: float, cycles: int) -> NDArray[np.float64]:
    """Sinusoids of each amplitude in turn (``cycles`` periods each), starting at 0 at rest."""
    period = cycles / freq
    x = np.zeros_like(t)
    for i, a in enumerate(amplitudes):
        m = (t >= i * period) & (t < (i + 1) * period)
        x[m] = a * np.sin(2 * np.pi * freq * (t[m] - i * period))
    return x


def reversal_position(t: NDArray[np.float64], turns: NDArray[np.float64], durations: NDArray[np.float64]) -> NDArray[np.float64]:
    """Half-cosine moves between successive turning points ``turns`` (the first one is the start),
    move ``j`` lasting ``durations[j]``; the position rests at the last turn afterwards."""
    x = np.full_like(t, turns[-1])
    t0 = 0.0
    x[t < 0] = turns[0]
    for j in range(len(turns) - 1):
        t1 = t0 + durations[j]
        m = (t >= t0) & (t < t1)
        s = (t[m] - t0) / durations[j]
        x[m] = turns[j] + (turns[j + 1] - turns[j]) * 0.5 * (1.0 - np.cos(np.pi * s))
        t0 = t1
    return x


# --------------------------------------------------------------------------- static map

def stribeck_force(v: NDArray[np.float64], fc: float, fs: float, vs: float, sigma: float, delta: float) -> NDArray[np.float64]:
    """Eq. 2: ``sign(v) (fc + (fs - fc) exp(-|v/vs|^delta)) + sigma v``."""
    v = np.asarray(v, float)
    return np.sign(v) * (fc + (fs - fc) * np.exp(-np.abs(v / vs) ** delta)) + sigma * v


@njit(cache=True)
def _mass_pid_loop(xref, vref, dist, q, T, nsub, m, fc, fs, vs, sigma, delta, kp, ki, kd, tf):  # type: ignore[no-untyped-def]
    n = xref.size
    h = T / nsub
    x = 0.0
    v = 0.0
    stuck = True
    integ = 0.0
    dfilt = 0.0
    yprev = 0.0
    alpha = tf / (tf + T)  # first-order filter on the derivative of the measured position
    pos = np.empty(n)
    cmd = np.empty(n)
    vel = np.empty(n)
    for j in range(n):
        y = q * math.floor(x / q + 0.5)
        e = xref[j] - y
        integ += T * e
        rate = (y - yprev) / T if j > 0 else 0.0
        yprev = y
        dfilt = alpha * dfilt + (1.0 - alpha) * rate
        u = kp * e + ki * integ + kd * (vref[j] - dfilt)  # derivative on the velocity error
        pos[j] = y
        cmd[j] = u
        vel[j] = v
        net = u + dist[j]
        for _ in range(nsub):
            if stuck:
                if abs(net) <= fs:
                    continue  # Karnopp: the static force holds the mass
                stuck = False
                sgn = 1.0 if net > 0 else -1.0
                a = (net - sgn * fs) / m
                vn = a * h
            else:
                sgn = 1.0 if v > 0 else -1.0
                fr = sgn * (fc + (fs - fc) * math.exp(-abs(v / vs) ** delta)) + sigma * v
                vn = v + h * (net - fr) / m
                if vn * v <= 0.0:  # velocity crosses zero inside the step: stop, then stick test
                    x += 0.5 * v * h
                    v = 0.0
                    stuck = True
                    continue
            x += 0.5 * (v + vn) * h
            v = vn
    return pos, cmd, vel


def velocity_profile(speeds: NDArray[np.float64], hold: NDArray[np.float64], accel: float, dwell: float, T: float) -> tuple[NDArray[np.float64], NDArray[np.float64], list[tuple[float, float, float]]]:
    """Reference velocity: for each speed, +v then -v, trapezoidal ramps at ``accel``, held for
    ``hold`` each, ``dwell`` at rest in between.  Returns ``(t, v_ref, plateaus)`` with the
    plateaus as ``(t_start, t_stop, v)`` of the held parts."""
    pieces: list[NDArray[np.float64]] = [np.zeros(int(round(dwell / T)))]
    plateaus = []
    t_now = pieces[0].size * T
    for v, th in zip(speeds, hold):
        for sgn in (1.0, -1.0):
            nr = max(int(math.ceil(v / accel / T)), 1)
            ramp = sgn * v * np.arange(1, nr + 1) / nr
            nh = int(round(th / T))
            seg = np.concatenate([ramp, np.full(nh, sgn * v), ramp[::-1][1:], np.zeros(1 + int(round(dwell / T)))])
            plateaus.append((t_now + nr * T, t_now + (nr + nh) * T, sgn * v))
            pieces.append(seg)
            t_now += seg.size * T
    vref = np.concatenate(pieces)
    t = np.arange(vref.size) * T
    return t, vref, plateaus


def simulate_velocity_run(xref: NDArray[np.float64], vref: NDArray[np.float64], dist: NDArray[np.float64], *, q: float, T: float, nsub: int, m: float,
                          fc: float, fs: float, vs: float, sigma: float, delta: float, kp: float, ki: float, kd: float, tf: float
                          ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Mass ``m`` with eq. 2 friction (Karnopp stiction at ``fs``) under a PID position loop
    sampled at ``T`` (command held, ``nsub`` Euler-trapezoid substeps), disturbance force
    ``dist`` per sample.  Returns the quantised position, the command force and the true
    velocity at the sample instants."""
    return _mass_pid_loop(np.ascontiguousarray(xref, float), np.ascontiguousarray(vref, float), np.ascontiguousarray(dist, float), float(q), float(T), int(nsub), float(m),
                          float(fc), float(fs), float(vs), float(sigma), float(delta), float(kp), float(ki), float(kd), float(tf))


# --------------------------------------------------------------------------- plant

def discretize_delayed(a: float, b: float, c: float, tau: float, T: float) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], int]:
    """Exact discretisation of ``a/(s^2+bs+c) e^{-s tau}`` with a zero-order-held input.

    With ``tau = n T + theta`` (``0 <= theta < T``) the input seen by the plant over
    ``[kT, kT + theta)`` is ``u[k-n-1]`` and over ``[kT + theta, (k+1)T)`` it is ``u[k-n]``:
    ``x[k+1] = Phi x[k] + G0 u[k-n] + G1 u[k-n-1]``, state ``(position, velocity)``.
    Returns ``Phi, G0, G1, n``.
    """
    A = np.array([[0.0, 1.0], [-c, -b]])
    B = np.array([0.0, a])
    n = int(math.floor(tau / T + 1e-12))
    theta = tau - n * T

    def phi_gamma(s: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        M = np.zeros((3, 3))
        M[:2, :2] = A
        M[:2, 2] = B
        E = expm(M * s)
        return E[:2, :2], E[:2, 2]

    Phi, _ = phi_gamma(T)
    Ph_rest, G0 = phi_gamma(T - theta)
    _, g_theta = phi_gamma(theta)
    G1 = Ph_rest @ g_theta
    return Phi, G0, G1, n


def simulate_plant_open(u: NDArray[np.float64], a: float, b: float, c: float, tau: float, T: float) -> NDArray[np.float64]:
    """Position (m) at the sample instants for the held input ``u`` (from rest)."""
    Phi, G0, G1, n = discretize_delayed(a, b, c, tau, T)
    u0 = np.concatenate([np.zeros(n), u])[: u.size]
    u1 = np.concatenate([np.zeros(n + 1), u])[: u.size]
    _, y, _ = dlsim((Phi, np.column_stack([G0, G1]), np.array([[1.0, 0.0]]), np.zeros((1, 2)), T), np.column_stack([u0, u1]))
    return y[:, 0]


@njit(cache=True)
def _plant_pid_loop(Phi, G0, G1, n, ref, rin, q, noise, T, kp, ki, kd, tf):  # type: ignore[no-untyped-def]
    N = ref.size
    x0 = 0.0
    x1 = 0.0
    buf = np.zeros(n + 2)  # buf[i] = u[k - i] after the shift
    integ = 0.0
    dfilt = 0.0
    eprev = 0.0
    alpha = tf / (tf + T)
    ymeas = np.full(N, np.nan)  # a diverging loop leaves NaN (the caller retries with lower gains)
    cmd = np.full(N, np.nan)
    for k in range(N):
        y = q * math.floor((x0 + noise[k]) / q + 0.5)
        e = ref[k] - y
        integ += T * e
        de = (e - eprev) / T if k > 0 else 0.0
        eprev = e
        dfilt = alpha * dfilt + (1.0 - alpha) * de
        u = kp * e + ki * integ + kd * dfilt + rin[k]
        for i in range(n + 1, 0, -1):
            buf[i] = buf[i - 1]
        buf[0] = u
        ymeas[k] = y
        cmd[k] = u
        un, un1 = buf[n], buf[n + 1]
        nx0 = Phi[0, 0] * x0 + Phi[0, 1] * x1 + G0[0] * un + G1[0] * un1
        nx1 = Phi[1, 0] * x0 + Phi[1, 1] * x1 + G0[1] * un + G1[1] * un1
        x0, x1 = nx0, nx1
        if abs(x0) > 1e6:
            break
    return ymeas, cmd


def simulate_plant_pid(ref: NDArray[np.float64], rin: NDArray[np.float64], noise: NDArray[np.float64], *, a: float, b: float, c: float, tau: float,
                       T: float, q: float, kp: float, ki: float, kd: float, tf: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Closed loop: PID on the quantised, noisy position (filtered derivative ``tf``), plus the
    input excitation ``rin``; reference ``ref``.  Returns the measured position and the drive."""
    Phi, G0, G1, n = discretize_delayed(a, b, c, tau, T)
    return _plant_pid_loop(Phi, G0, G1, n, np.ascontiguousarray(ref, float), np.ascontiguousarray(rin, float), float(q),
                           np.ascontiguousarray(noise, float), float(T), float(kp), float(ki), float(kd), float(tf))
