"""EMPS research scaffolding: data, benchmark metrics, and a numba simulator of the rigid axis.

Everything is SI.  The simulator integrates a rigid body with a general friction law at
``nsub`` substeps per sample; the drive command is held over each sample (zero-order hold) and
may be delayed by a fractional ``tau``; the force of each substep is the exact mean of the
delayed held force over that substep.

Friction with stiction is handled by the implicit (set-valued) update: at each substep the
velocity ``v1`` solves ``M (v1 - v0)/h = F - Fv(v1) v1 - Fc(v0) sgn(v1)`` where ``sgn(0)`` is
the interval [-1, 1]: the axis stays stuck while ``|M v0/h + F| <= Fs``.  This is exact for
the set-valued law as ``h -> 0`` and never chatters.

Parameter vector layout (``P_*`` indices) is fixed; optional effects are off at zero.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.io as sio
from numba import njit

DATA = "/work/shared/data/emps/"
DT = 1e-3
N_SKIP = 20  # benchmark: RMSE after the first 20 samples


@dataclass
class Run:
    name: str
    t: np.ndarray
    qm: np.ndarray
    qg: np.ndarray
    vir: np.ndarray
    pulses: np.ndarray
    gtau: float
    kp: float
    kv: float

    @property
    def force(self) -> np.ndarray:
        return self.gtau * self.vir


def load(name: str) -> Run:
    d = sio.loadmat(DATA + name)
    f = lambda k: np.ascontiguousarray(d[k].ravel(), dtype=float)  # noqa: E731
    pulses = f("pulses_N") if "pulses_N" in d else np.zeros(d["t"].size)
    return Run(name, f("t"), f("qm"), f("qg"), f("vir"), pulses, float(d["gtau"].item()), float(d["kp"].item()), float(d["kv"].item()))


def runs() -> tuple[Run, Run]:
    return load("DATA_EMPS.mat"), load("DATA_EMPS_PULSES.mat")


def rmse_open(q_sim: np.ndarray, run: Run) -> float:
    """Benchmark open-loop score: RMSE (m) of simulated qm after the first 20 samples."""
    e = q_sim[N_SKIP:] - run.qm[N_SKIP:]
    return float(np.sqrt(np.mean(e * e)))


def rel(y: np.ndarray, yh: np.ndarray) -> float:
    return float(100.0 * np.linalg.norm(y - yh) / np.linalg.norm(y))


# ------------------------------------------------------------------------------------------
# Parameter layout
P_M, P_FVP, P_FVN, P_FCP, P_FCN, P_OFF, P_DS, P_VS, P_SD, P_TAU = range(10)
# nonlinear viscous: F += Fv2_dir * v*|v|  (per direction)
P_FV2P, P_FV2N = 10, 11
# friction level that relaxes with dissipated energy ("warm-up"): Fc and Fv scaled by
# (1 + a_c * s) and (1 + a_v * s), with s in [0, 1] decaying as ds/dt = -s*P/E0 (P dissipated power)
P_WAC, P_WAV, P_WE0 = 12, 13, 14
# first-order temperature-like state: x' = (P - x)/T_th, friction scaled by (1 - b_c x), (1 - b_v x)
P_TBC, P_TBV, P_TTH = 15, 16, 17
# compliance: motor mass fraction, spring k, damper c (load = M - m1); 0 disables
P_MFRAC, P_K, P_C = 18, 19, 20
# first-order lag of the drive (current loop): time constant Te (s); 0 disables
P_TE = 21
N_BASE = 22


def base_params(M=95.0, Fv=203.0, Fc=20.4, off=-3.16) -> np.ndarray:
    p = np.zeros(N_BASE)
    p[P_M] = M
    p[P_FVP] = p[P_FVN] = Fv
    p[P_FCP] = p[P_FCN] = Fc
    p[P_OFF] = off
    p[P_VS] = 0.01
    p[P_SD] = 2.0
    p[P_WE0] = 1e3
    p[P_TTH] = 10.0
    return p


@njit(cache=True)
def _legendre(x, c, out_unused=0.0):
    """sum_k c[k] P_k(x) for x in [-1, 1] (Bonnet recurrence)."""
    n = c.size
    if n == 0:
        return 0.0
    p0 = 1.0
    s = c[0] * p0
    if n == 1:
        return s
    p1 = x
    s += c[1] * p1
    for k in range(2, n):
        p2 = ((2 * k - 1) * x * p1 - (k - 1) * p0) / k
        s += c[k] * p2
        p0, p1 = p1, p2
    return s


@njit(cache=True)
def _fourier(q, per, cs):
    """sum_j a_j cos(2 pi q / per_j) + b_j sin(...); cs = [a_0, b_0, a_1, b_1, ...]."""
    s = 0.0
    for j in range(per.size):
        w = 2.0 * np.pi * q / per[j]
        s += cs[2 * j] * np.cos(w) + cs[2 * j + 1] * np.sin(w)
    return s


@njit(cache=True)
def _cum_u(U, u, x, dt):
    """Integral of the held input from 0 to x (x may be negative: u[0] held before 0)."""
    if x <= 0.0:
        return x * u[0]
    j = int(x / dt)
    if j >= u.size:
        return U[u.size] + (x - u.size * dt) * u[u.size - 1]
    return U[j] + (x - j * dt) * u[j]


@njit(cache=True)
def simulate(p, cq, cf, per, cfq, cff, q_lo, q_hi, n, dt, nsub, q0, v0,
             closed, force_in, qg, pulses, gtau, kp, kv, umax, q_out, u_out, v_out, bk, bf):
    """Simulate the axis for n samples.

    Open loop (closed=False): force_in[k] (N) is held over [t_k, t_k+1) (then delayed by tau).
    Closed loop: vir[k] = sat(kp kv (qg - q) - kv qdot + pulses) from the simulated samples;
    the force is gtau * vir.  q_out, u_out (force, N), v_out receive the samples.

    Position force g(q) = Legendre(cq) + Fourier(per, cfq); position friction
    h(q) sgn(v) = (Legendre(cf) + Fourier(per, cff)) sgn(v).

    Pre-sliding: Maxwell-slip blocks (stiffness bk[i], break force bf[i]) in parallel with the
    rigid (set-valued) Coulomb level; the block forces are explicit within a substep, which is
    stable while h sqrt(sum bk / M) << 1.  The axis starts with relaxed blocks.
    """
    M = p[P_M]
    h = dt / nsub
    tau = p[P_TAU]
    mid = 0.5 * (q_lo + q_hi)
    half = 0.5 * (q_hi - q_lo)
    # compliance
    mfrac = p[P_MFRAC]
    comp = mfrac > 0.0
    m1 = M * mfrac if comp else M
    m2 = M - m1
    kk = p[P_K]
    cc = p[P_C]
    U = np.zeros(n + 1)
    u = np.zeros(n)
    q = q0
    v = v0
    x2 = q0  # load position (compliance)
    v2 = v0
    s_w = 1.0  # warm-up state
    x_th = 0.0  # thermal state
    Te = p[P_TE]
    Fa = 0.0  # drive force through the lag
    lag_init = False
    nb = bk.size
    sb = np.zeros(nb)
    # controller memory consistent with the initial velocity (the run starts in motion)
    q_prev = q0 - v0 * dt
    qf_prev = q_prev - 0.5 * v0 * dt
    for k in range(n):
        q_out[k] = q
        v_out[k] = v
        if closed:
            qf = 0.5 * q + 0.5 * q_prev
            qd = (qf - qf_prev) / dt
            vir = kp * kv * (qg[k] - q) - kv * qd + pulses[k]
            if vir > umax:
                vir = umax
            elif vir < -umax:
                vir = -umax
            u[k] = gtau * vir
            qf_prev = qf
            q_prev = q
        else:
            u[k] = force_in[k]
        u_out[k] = u[k]
        U[k + 1] = U[k] + dt * u[k]
        t0 = k * dt
        for i in range(nsub):
            a = t0 + i * h
            b = a + h
            if tau == 0.0:
                F = u[k]
            else:
                F = (_cum_u(U, u, b - tau, dt) - _cum_u(U, u, a - tau, dt)) / h
            if Te > 0.0:
                if not lag_init:
                    Fa = F
                    lag_init = True
                ex = np.exp(-h / Te)
                Fmean = F + (Fa - F) * (Te / h) * (1.0 - ex)
                Fa = F + (Fa - F) * ex
                F = Fmean
            xq = (q - mid) / half
            if xq > 1.0:
                xq = 1.0
            elif xq < -1.0:
                xq = -1.0
            gq = _legendre(xq, cq) + _fourier(q, per, cfq)
            hq = _legendre(xq, cf) + _fourier(q, per, cff)
            # friction levels, scaled by the state-dependent factors
            scale_c = (1.0 + p[P_WAC] * s_w) * (1.0 - p[P_TBC] * x_th)
            scale_v = (1.0 + p[P_WAV] * s_w) * (1.0 - p[P_TBV] * x_th)
            av = abs(v)
            strib = p[P_DS] * np.exp(-(av / p[P_VS]) ** p[P_SD]) if p[P_DS] != 0.0 else 0.0
            fcp = (p[P_FCP] + hq + strib) * scale_c
            fcn = (p[P_FCN] + hq + strib) * scale_c
            fvp = p[P_FVP] * scale_v + p[P_FV2P] * av
            fvn = p[P_FVN] * scale_v + p[P_FV2N] * av
            Fext = F - p[P_OFF] - gq
            for i in range(nb):
                Fext -= sb[i]
            if comp:
                Fext -= kk * (q - x2) + cc * (v - v2)
            mh = m1 / h
            pm = mh * v + Fext
            if pm > fcp:
                v1 = (pm - fcp) / (mh + fvp)
            elif pm < -fcn:
                v1 = (pm + fcn) / (mh + fvn)
            else:
                v1 = 0.0
            # dissipated friction power for the state-dependent effects
            if v1 > 0.0:
                pw = (fcp + fvp * v1) * v1
            elif v1 < 0.0:
                pw = (fcn - fvn * v1) * (-v1)
            else:
                pw = 0.0
            if p[P_WAC] != 0.0 or p[P_WAV] != 0.0:
                s_w *= np.exp(-h * pw / p[P_WE0])
            if p[P_TBC] != 0.0 or p[P_TBV] != 0.0:
                x_th += h * (pw - x_th) / p[P_TTH]
            if comp:
                # load: m2 a2 = k (q - x2) + c (v - v2), semi-implicit
                a2 = (kk * (q - x2) + cc * (v1 - v2)) / m2
                v2n = v2 + h * a2
                x2 += 0.5 * h * (v2 + v2n)
                v2 = v2n
            dx = 0.5 * h * (v + v1)
            for i in range(nb):
                si = sb[i] + bk[i] * dx
                if si > bf[i]:
                    si = bf[i]
                elif si < -bf[i]:
                    si = -bf[i]
                sb[i] = si
            q += dx
            v = v1
    return 0


def sim(p, run: Run, *, closed=False, nsub=10, cq=None, cf=None, per=None, cfq=None, cff=None,
        q_range=(0.0, 0.25), v0=None, q0=None, umax=10.0, blocks=None):
    """Convenience wrapper: returns (q, force, v) at the samples."""
    n = run.t.size
    e = np.zeros(0)
    cq = e if cq is None else np.asarray(cq, float)
    cf = e if cf is None else np.asarray(cf, float)
    per = e if per is None else np.asarray(per, float)
    cfq = np.zeros(2 * per.size) if cfq is None else np.asarray(cfq, float)
    cff = np.zeros(2 * per.size) if cff is None else np.asarray(cff, float)
    if q0 is None:
        q0 = run.qm[0]
    if v0 is None:
        v0 = initial_velocity(run)
    qo, uo, vo = np.empty(n), np.empty(n), np.empty(n)
    if blocks is None:
        bk = bf = np.zeros(0)
    else:
        bf = np.asarray(blocks[0], float)
        bk = bf / np.asarray(blocks[1], float)  # blocks = (break forces N, break displacements m)
    simulate(np.asarray(p, float), cq, cf, per, cfq, cff, q_range[0], q_range[1], n, DT, nsub, q0, v0,
             closed, run.force, run.qg, run.pulses, run.gtau, run.kp, run.kv, umax, qo, uo, vo, bk, bf)
    return qo, uo, vo


def initial_velocity(run: Run, n: int = 5) -> float:
    """Velocity at t0 from a quadratic fit to the first n samples (the protocol's init window)."""
    c = np.polyfit(np.arange(n) * DT, run.qm[:n], 2)
    return float(c[1])


# ------------------------------------------------------------------------------------------
# Named parameterisation for output-error fitting

NAMED = {"M": P_M, "Fv+": P_FVP, "Fv-": P_FVN, "Fc+": P_FCP, "Fc-": P_FCN, "off": P_OFF,
         "dS": P_DS, "vS": P_VS, "dSexp": P_SD, "tau": P_TAU, "Fv2+": P_FV2P, "Fv2-": P_FV2N,
         "wac": P_WAC, "wav": P_WAV, "wE0": P_WE0, "tbc": P_TBC, "tbv": P_TBV, "tth": P_TTH,
         "mfrac": P_MFRAC, "k": P_K, "c": P_C, "Te": P_TE}


class Model:
    """A free-parameter view on the simulator: names -> p indices or basis coefficients.

    Coefficient names: ``cqK`` (Legendre force, degree K), ``cfK`` (Legendre friction level),
    ``fqaJ``/``fqbJ`` (Fourier force at period J), ``ffaJ``/``ffbJ`` (Fourier friction).
    ``sym`` ties Fv-/Fc- to Fv+/Fc+ (names 'Fv', 'Fc').
    """

    def __init__(self, values: dict, free: list[str], n_cq=0, n_cf=0, periods=(), q_range=(0.0, 0.25), n_blocks=0):
        self.n_blocks = n_blocks
        self.values = dict(values)
        self.free = list(free)
        self.n_cq, self.n_cf = n_cq, n_cf
        self.periods = np.asarray(periods, float)
        self.q_range = q_range

    def x0(self):
        return np.array([self.values.get(n, 0.0) for n in self.free])

    def with_x(self, x):
        m = Model(self.values, self.free, self.n_cq, self.n_cf, self.periods, self.q_range, self.n_blocks)
        for n, v in zip(self.free, x):
            m.values[n] = float(v)
        return m

    def unpack(self):
        p = base_params()
        p[P_OFF] = 0.0
        # symmetric levels first: per-direction names, when present, override them
        if "Fv" in self.values:
            p[P_FVP] = p[P_FVN] = self.values["Fv"]
        if "Fc" in self.values:
            p[P_FCP] = p[P_FCN] = self.values["Fc"]
        for n, v in self.values.items():
            if n in NAMED:
                p[NAMED[n]] = v
        cq = np.array([self.values.get(f"cq{k}", 0.0) for k in range(self.n_cq)])
        cf = np.array([self.values.get(f"cf{k}", 0.0) for k in range(self.n_cf)])
        np_ = self.periods.size
        cfq = np.array([self.values.get(f"fq{ab}{j}", 0.0) for j in range(np_) for ab in "ab"])
        cff = np.array([self.values.get(f"ff{ab}{j}", 0.0) for j in range(np_) for ab in "ab"])
        return p, cq, cf, cfq, cff

    def simulate(self, run: Run, *, closed=False, nsub=5, v0=None):
        p, cq, cf, cfq, cff = self.unpack()
        blocks = None
        if self.n_blocks:
            blocks = (np.array([self.values[f"bf{i}"] for i in range(self.n_blocks)]),
                      np.array([self.values[f"bd{i}"] for i in range(self.n_blocks)]))
        return sim(p, run, closed=closed, nsub=nsub, cq=cq, cf=cf, per=self.periods, cfq=cfq, cff=cff,
                   q_range=self.q_range, v0=v0, blocks=blocks)

    def scores(self, est: Run, val: Run, nsub=5):
        o = [rmse_open(self.simulate(r, nsub=nsub)[0], r) * 1e3 for r in (est, val)]
        c = [rel(r.force, self.simulate(r, closed=True, nsub=nsub)[1]) for r in (est, val)]
        return {"open_mm": o, "closed_force_pct": c}


def typical_scale(name: str, v: float) -> float:
    if name.startswith("bd"):
        return 1e-5
    s = {"Te": 1e-3, "tau": 1e-3, "vS": 0.01, "dSexp": 1.0, "wE0": 1e3, "tth": 10.0, "mfrac": 0.5, "k": 1e6, "c": 1e3}.get(name)
    if s is not None:
        return s
    return max(abs(v), 1.0)


def fit_oe(model: Model, run: Run, *, closed=False, nsub=5, bounds=None, verbose=0, max_nfev=200, weights=None):
    """Output-error least squares: open loop on position (m), closed loop on force (N)."""
    from scipy.optimize import least_squares

    x0 = model.x0()
    sc = np.array([typical_scale(n, v) for n, v in zip(model.free, x0)])
    counter = [0]

    def resid(z):
        counter[0] += 1
        m = model.with_x(z * sc)
        q, f, _ = m.simulate(run, closed=closed, nsub=nsub)
        if closed:
            r = (f - run.force)
        else:
            r = (q - run.qm)[N_SKIP:]
        if not np.all(np.isfinite(r)):
            return np.full(r.size, 1e3)
        return r if weights is None else r * weights

    lb = -np.inf * np.ones(x0.size)
    ub = np.inf * np.ones(x0.size)
    if bounds:
        for i, n in enumerate(model.free):
            if n in bounds:
                lb[i], ub[i] = bounds[n]
    res = least_squares(resid, x0 / sc, bounds=(lb / sc, ub / sc), x_scale=1.0, diff_step=1e-4,
                        verbose=verbose, max_nfev=max_nfev)
    m = model.with_x(res.x * sc)
    # standard errors from the Jacobian
    J = res.jac / sc[None, :]
    dof = max(res.fun.size - x0.size, 1)
    s2 = 2 * res.cost / dof
    try:
        cov = np.linalg.pinv(J.T @ J) * s2
        std = np.sqrt(np.clip(np.diag(cov), 0, None))
    except np.linalg.LinAlgError:
        std = np.full(x0.size, np.nan)
    m.std = dict(zip(model.free, std))
    m.nfev = counter[0]
    return m, res
