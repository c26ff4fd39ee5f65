"""NumPy reference of the adaptive EKF step of `twin_core::aekf::Aekf::step`
for the seed's kinematic model, timed, for the side-by-side benchmark.

This is the recursion as the seed ran it, a Python loop over steps doing
NumPy arithmetic on 4x4 matrices, but with everything the Rust step does:

- lambda = exp(-dt / tau) per step, Q_k = Q_c dt;
- masked measurement components (zero row in H, zero innovation, the row and
  column of R cleared with its diagonal kept, or 1 if it was not positive);
- the Joseph-form covariance update;
- per-component anti-windup forgetting (`forgetting_factors`) from the
  information gain diag(Omega^T Sigma^-1 Omega) and the held information;
- steps 8-10 in the form with S_f = D^-1/2 S D^-1/2:
  Gamma = S_f Omega^T (Sigma + Omega S_f Omega^T)^-1, S = S_f - Gamma Omega S_f;
- held and recent information, course wrapping of the innovation and of the
  posterior, the NIS;
- the optional Q/R adaptation (both forms of R) for use from the next step;
- a step that fails (a matrix that is not positive definite, a non-finite
  value, a non-positive variance) leaves the estimate as it was.

Model (state [north, east, U, chi], input [a, r], faults [theta_a, theta_r]):
    next = [n + dt U cos chi, e + dt U sin chi,
            U + dt (1 - theta_a) a, wrap(chi + dt (1 - theta_r) r)]
    Psi  = -B diag(u),  B = dt [[0,0],[0,0],[1,0],[0,1]];  h(x) = x.

Usage:
    python3 bench/numpy_aekf.py TRIAL.json --out RESULT.json [--repeats 7]

The trial file is written by `cargo run --release -p twin-bench -- numpy`;
the result holds the per-step estimates (theta, x, nis, ok) and the timing
(median over repeats of the whole trial, time.perf_counter, ns per step).
Exits with status 3 and a message on stderr if NumPy is missing.
"""

import argparse
import json
import math
import platform
import statistics
import sys
import time

try:
    import numpy as np
except ImportError:
    sys.stderr.write(
        "numpy_aekf.py: NumPy is not installed for this Python "
        f"({sys.executable}). Install it with:\n"
        "    python3 -m pip install -r requirements.txt\n"
    )
    sys.exit(3)

PI = math.pi
TAU = 2.0 * math.pi
COURSE = 3  # index of the course (an angle) in the state and the measurement


def wrap_pi(a):
    """Wraps an angle to [-pi, pi), as `twin_core::geodesy::wrap_pi` does
    (same branches, so the same rounding)."""
    if -PI <= a < PI:
        return a
    if PI <= a < 3.0 * PI:
        w = a - TAU
        if w < PI:
            return max(w, -PI)
    elif -3.0 * PI <= a < -PI:
        w = a + TAU
        if w >= -PI:
            return w if w < PI else -PI
    if not math.isfinite(a):
        return a
    w = (a + PI) % TAU - PI
    return w - TAU if w >= PI else w


class Config:
    """The filter's tuning, from the trial file's `config`."""

    def __init__(self, c):
        self.q_c = np.array(c["process_noise_density"], dtype=float)
        self.r = np.array(c["measurement_noise"], dtype=float)
        self.tau = float(c["forgetting_time_constant_s"])
        self.s0 = np.array(c["initial_fault_covariance"], dtype=float)
        self.ratio_min = float(c["anti_windup_ratio"])
        adapt = c.get("noise_adaptation")
        self.adapt = adapt is not None
        if self.adapt:
            self.adapt_factor = float(adapt["factor"])
            self.adapt_q = bool(adapt["adapt_process_noise"])
            self.adapt_r = adapt.get("measurement_noise_form")  # None or a name
            if self.adapt_r not in (None, "post_fit_residual", "authors_code"):
                raise ValueError(f"unknown measurement_noise_form {self.adapt_r!r}")


class State:
    """The estimate carried from step to step (`AekfState`)."""

    __slots__ = ("x", "p", "ups", "s", "theta", "q_c", "r", "held", "recent")

    def __init__(self, x, p, ups, s, theta, q_c, r, held, recent):
        self.x = x
        self.p = p
        self.ups = ups
        self.s = s
        self.theta = theta
        self.q_c = q_c
        self.r = r
        self.held = held
        self.recent = recent


def forgetting_factors(lam, gain, held, ratio_min):
    """Per-component forgetting with anti-windup (`forgetting_factors`)."""
    if ratio_min <= 0.0:
        return np.full(gain.shape, lam)
    gain = np.maximum(gain, 0.0)
    positive = held > 0.0
    ratio = np.where(
        positive,
        gain / ((1.0 - lam) * np.where(positive, held, 1.0)),
        np.where(gain > 0.0, ratio_min, 0.0),
    )
    return 1.0 - (1.0 - lam) * np.minimum(ratio / ratio_min, 1.0)


EYE4 = np.eye(4)


def step(cfg, st, a, r_in, y, avail, all_avail, dt):
    """One adaptive-EKF step. Returns (new State, nis), or None if the step is
    refused (the caller then keeps the old state, as the Rust filter does)."""
    if not (dt > 0.0 and math.isfinite(dt)):
        return None
    lam = math.exp(-dt / cfg.tau)
    x = st.x
    theta = st.theta

    # Steps 1 and 11 (first half): transition, F and Psi at xhat(k|k).
    speed = x[2]
    course = x[3]
    sin_c = math.sin(course)
    cos_c = math.cos(course)
    x_bar = np.array(
        [
            x[0] + dt * speed * cos_c,
            x[1] + dt * speed * sin_c,
            speed + dt * (1.0 - theta[0]) * a,
            wrap_pi(course + dt * (1.0 - theta[1]) * r_in),
        ]
    )
    if not np.isfinite(x_bar).all():
        return None
    f = np.array(
        [
            [1.0, 0.0, dt * cos_c, -dt * speed * sin_c],
            [0.0, 1.0, dt * sin_c, dt * speed * cos_c],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )
    psi = np.array([[0.0, 0.0], [0.0, 0.0], [-dt * a, 0.0], [0.0, -dt * r_in]])

    # Step 2.
    q_step = st.q_c * dt
    p_prior = f @ st.p @ f.T + q_step

    # Measurement model h(x) = x at the predicted state, missing components masked.
    innov = y - x_bar
    innov[COURSE] = wrap_pi(innov[COURSE])
    if all_avail:
        h = EYE4
        r = st.r
    else:
        h = EYE4 * avail[:, None]
        innov = np.where(avail, innov, 0.0)
        keep = np.diagonal(st.r)
        r = st.r * np.outer(avail, avail)
        missing = ~avail
        r[missing, missing] = np.where(keep[missing] > 0.0, keep[missing], 1.0)

    # Steps 3-4, with Omega (step 6) and the NIS sharing one solve with Sigma.
    h_p = h @ p_prior
    sigma = h_p @ h.T + r
    f_ups_psi = f @ st.ups + psi
    omega = h @ f_ups_psi
    try:
        np.linalg.cholesky(sigma)  # refuse a Sigma that is not positive definite
    except np.linalg.LinAlgError:
        return None
    solved = np.linalg.solve(sigma, np.hstack((h_p, omega, innov[:, None])))
    k = solved[:, :4].T
    sigma_inv_omega = solved[:, 4:6]
    sigma_inv_innov = solved[:, 6]

    # Step 5 (Joseph form) and step 7.
    ikh = EYE4 - k @ h
    p_post = ikh @ p_prior @ ikh.T + (k @ r) @ k.T
    ups = ikh @ f_ups_psi

    # Forgetting per fault component, then steps 8-10 with S_f = D^-1/2 S D^-1/2.
    info_gain = np.diagonal(omega.T @ sigma_inv_omega)
    forgetting = forgetting_factors(lam, info_gain, st.held, cfg.ratio_min)
    scale = 1.0 / np.sqrt(forgetting)
    s_forgot = st.s * np.outer(scale, scale)
    omega_s = omega @ s_forgot
    lambda_mat = sigma + omega_s @ omega.T
    try:
        np.linalg.cholesky(lambda_mat)
    except np.linalg.LinAlgError:
        return None
    gamma = np.linalg.solve(lambda_mat, omega_s).T
    s_post = s_forgot - gamma @ omega_s
    s_post = (s_post + s_post.T) * 0.5

    # Steps 11-13.
    d_theta = gamma @ innov
    theta_new = theta + d_theta
    x_post = x_bar + k @ innov + ups @ d_theta
    x_post[COURSE] = wrap_pi(x_post[COURSE])

    nis = float(innov @ sigma_inv_innov)
    if not math.isfinite(nis):
        return None
    held = forgetting * st.held + info_gain
    recent = st.recent * lam + info_gain

    # Optional noise adaptation, for use from the next step.
    q_c = st.q_c
    r_next = st.r
    if cfg.adapt:
        fa = cfg.adapt_factor
        if cfg.adapt_q:
            ki = k @ innov
            q_new = q_step * fa + np.outer(ki, ki) * (1.0 - fa)
            q_c = (q_new + q_new.T) * (0.5 / dt)
        if cfg.adapt_r is not None:
            if cfg.adapt_r == "post_fit_residual":
                eps = y - x_post
                eps[COURSE] = wrap_pi(eps[COURSE])
                eps = np.where(avail, eps, 0.0)
                spread = h @ p_post @ h.T
            else:  # "authors_code"
                eps = innov
                spread = h @ p_prior @ h.T
            sample = np.outer(eps, eps) + spread
            both = np.outer(avail, avail)
            r_next = np.where(both, fa * st.r + (1.0 - fa) * sample, st.r)
            r_next = (r_next + r_next.T) * 0.5
            try:
                np.linalg.cholesky(r_next)
            except np.linalg.LinAlgError:
                r_next = st.r

    # The Rust step's sanity check (`AekfState::is_sane`).
    if not (
        np.isfinite(x_post).all()
        and np.isfinite(p_post).all()
        and np.isfinite(s_post).all()
        and np.isfinite(theta_new).all()
        and np.isfinite(ups).all()
        and (np.diagonal(p_post) > 0.0).all()
        and (np.diagonal(s_post) > 0.0).all()
    ):
        return None
    return State(x_post, p_post, ups, s_post, theta_new, q_c, r_next, held, recent), nis


def load_trial(path):
    """Reads a trial file into the configuration, the initial state and the
    per-step arrays (converted once, outside the timed loop)."""
    with open(path, encoding="utf-8") as fh:
        trial = json.load(fh)
    if trial.get("model") != "kinematic":
        raise ValueError(f"unsupported model {trial.get('model')!r}")
    cfg = Config(trial["config"])
    init = trial["initial"]
    start = State(
        np.array(init["x"], dtype=float),
        np.array(init["p"], dtype=float),
        np.zeros((4, 2)),
        cfg.s0.copy(),
        np.array(init["theta"], dtype=float),
        cfg.q_c.copy(),
        cfg.r.copy(),
        np.zeros(2),
        np.zeros(2),
    )
    s = trial["steps"]
    avail = np.array(s["available"], dtype=bool)
    steps = [
        (float(u[0]), float(u[1]), y, m, bool(m.all()), float(dt))
        for dt, u, y, m in zip(
            s["dt_s"], s["input"], np.array(s["y"], dtype=float), avail, strict=True
        )
    ]
    return cfg, start, steps


def run(cfg, start, steps, record):
    """Runs the whole trial from `start`. With `record`, returns the
    per-step theta, x, nis (None where refused) and ok flags."""
    st = start
    out = [] if record else None
    for a, r_in, y, avail, all_avail, dt in steps:
        res = step(cfg, st, a, r_in, y, avail, all_avail, dt)
        if res is not None:
            st = res[0]
        if record:
            out.append((st.theta.tolist(), st.x.tolist(), None if res is None else res[1]))
    return st, out


def main():
    """Command line: run, time, write the result."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("trial", help="trial JSON written by twin-bench")
    ap.add_argument("--out", required=True, help="where to write the result JSON")
    ap.add_argument("--repeats", type=int, default=7, help="timed runs of the whole trial")
    args = ap.parse_args()

    cfg, start, steps = load_trial(args.trial)
    # The recorded run doubles as the warm-up.
    _, rec = run(cfg, start, steps, record=True)
    times = []
    for _ in range(max(1, args.repeats)):
        t0 = time.perf_counter()
        run(cfg, start, steps, record=False)
        times.append(time.perf_counter() - t0)
    n = max(1, len(steps))
    result = {
        "theta": [r[0] for r in rec],
        "x": [r[1] for r in rec],
        "nis": [r[2] for r in rec],
        "ok": [r[2] is not None for r in rec],
        "timing": {
            "steps": len(steps),
            "repeats": len(times),
            "ns_per_step_median": statistics.median(times) / n * 1e9,
            "ns_per_step_min": min(times) / n * 1e9,
            "python": platform.python_version(),
            "numpy": np.__version__,
        },
    }
    with open(args.out, "w", encoding="utf-8") as fh:
        json.dump(result, fh)


if __name__ == "__main__":
    main()
