"""Measure a field-oriented SPM drive's torque envelope with motulator.

Standalone (imports only motulator, numpy, scipy and the standard library):

    python motulator_check.py < request.json > result.json

Request (JSON object): R (ohm per phase), L (H per phase, Ld = Lq), psi (V s,
PM flux linkage, peak phase, electrical), n_p (pole pairs), u_dc (V), i_max
(A, peak phase); for the torque mode also field_weakening (bool), speeds
(mechanical rad/s, list); and
optionally J (kg m^2; unused: the speed is imposed). Optional simulation knobs
(defaults in DEFAULTS below): T_s, t_stop, window, alpha_c, alpha_fw, k_u,
overmodulation, tau_ref, pwm, workers.

Two modes (key "mode"):

- "torque" (default, schema motulator-check/1): for every speed, two runs are
  made, with torque reference +tau_ref and -tau_ref (tau_ref defaults to 10x the
  current-limited torque). The rotor speed is held by motulator's
  ExternalRotorSpeed. Results are time averages over the last `window` fraction
  of each run.
- "references" (schema motulator-check/2): "points" is a list of
  {"speed": mech rad/s, "i_d": A, "i_q": A}; field_weakening and speeds are
  not used. Each point is one run whose current reference is fixed at
  i_d + j i_q, bypassing motulator's reference generator. The output reports
  whether the drive holds it (held_control), plus the steady torque and
  currents, the voltage ratio and the tracking error. Extra knobs: start
  ("steady" or "rest"), and t_stop, which defaults to 3 ms here. Each output
  field is explained in the output's "notes".

See README.md next to this file.
"""

import json
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from importlib.metadata import version

import numpy as np

DEFAULTS = {
    "T_s": 20e-6,  # controller sampling period (s); motulator default 250e-6
    "t_stop": 0.03,  # simulated time per run (s)
    "window": 0.25,  # averaging window: the last 25 % of the run
    "alpha_c": 2 * math.pi * 1000,  # current-control bandwidth (rad/s); motulator default 2*pi*200
    "alpha_fw": 2 * math.pi * 50,  # field-weakening bandwidth (rad/s); motulator default 2*pi*20
    "k_u": 1.0,  # voltage utilisation of the reference generator; motulator default 0.95
    "overmodulation": "linear",  # "linear" (circle u_dc/sqrt3), or motulator's "MME", "MPE", "six_step"
    "tau_ref": None,  # torque reference magnitude (N m); None -> 10 x 1.5 n_p psi i_max
    "pwm": "zoh",  # "zoh" (motulator default, averaged) or "carrier" (CarrierComparison)
    "workers": None,  # processes; None -> min(2, os.cpu_count())
}

# references mode: its own defaults for these keys (the rest as DEFAULTS)
REF_DEFAULTS = {
    "t_stop": 0.003,  # simulated time per point (s): decisions identical to 30 ms runs on the sample motor
    "start": "steady",  # "steady": start in the ideal steady state of the reference; "rest": zero current
}

TRACK_TOL = 0.02  # held control: |mean sampled current - mean reference| <= 2 % of i_max, ...
SAT_TOL = 1e-3  # ... the unlimited voltage reference never above the limit by more than 0.1 %, ...
OVER_TOL = 0.02  # ... and the mean current amplitude within i_max + 2 %
SETTLE_TOL = 0.005  # settled: mean torque of the last two half-windows within 0.5 % of Kt i_max
REF_TRACK_TOL = 0.005  # references mode: held if |mean sampled i - reference| <= 0.5 % of i_max + offset, ...
# ... where offset = mean|u_ref| (w_e T_s)^2 / (8 alpha_c L) (see README), and max |u_ref| <= u_dc/sqrt3.
REF_SETTLE_TOL = 0.002  # references mode: settled if the two half-window mean currents differ by <= 0.2 % i_max


def _linear_pwm_class():
    from motulator.common.control._control import PWM  # the class motulator's controllers instantiate
    from motulator.common.utils import abc2complex

    class LinearRangePWM(PWM):
        """motulator's PWM with the voltage reference clipped to the SVPWM circle |u| <= u_dc/sqrt(3).

        Only the magnitude is limited (angle kept), after motulator's own delay compensation and
        before its duty-ratio computation, so the realized voltage never enters overmodulation.
        """

        def output(self, T_s, ref_u_cs, u_dc, w):
            ref_u_cs = np.exp(1j * self.k_comp * T_s * w) * ref_u_cs
            lim = u_dc / np.sqrt(3)
            if abs(ref_u_cs) > lim:
                ref_u_cs = ref_u_cs * (lim / abs(ref_u_cs))
            d_abc = self.duty_ratios(ref_u_cs, u_dc)
            return d_abc, abc2complex(d_abc) * u_dc

    return LinearRangePWM


_trapezoid = np.trapezoid  # numpy >= 2.0


def _twa(t, x, mask):
    """Time-weighted average of x over the masked part of the (non-uniform) solver grid."""
    tt, xx = t[mask], x[mask]
    return _trapezoid(xx, tt) / (tt[-1] - tt[0])


def _drive(req, cfg, w_M, fw):
    """motulator model (imposed speed w_M) and its sensored CurrentVectorControl with the configured PWM."""
    import motulator.drive.control.sm as control
    from motulator.drive import model
    from motulator.drive.utils import SynchronousMachinePars

    R, L, psi, n_p = req["R"], req["L"], req["psi"], int(req["n_p"])
    u_dc, i_max = req["u_dc"], req["i_max"]
    u_lim = u_dc / math.sqrt(3)
    kt = 1.5 * n_p * psi

    par = SynchronousMachinePars(n_p=n_p, R_s=R, L_d=L, L_q=L, psi_f=psi)
    machine = model.SynchronousMachine(par)
    mechanics = model.ExternalRotorSpeed(w_M=lambda t: w_M + 0 * t)
    converter = model.VoltageSourceConverter(u_dc=u_dc)
    mdl = model.Drive(converter, machine, mechanics)
    if cfg["pwm"] == "carrier":
        mdl.pwm = model.CarrierComparison()

    w_base = u_lim / psi  # electrical no-load speed: sets motulator's field-weakening gain k_fw
    rcfg = control.CurrentReferenceCfg(par, max_i_s=i_max, nom_w_m=w_base, alpha_fw=cfg["alpha_fw"], k_u=cfg["k_u"])
    if not fw:
        # i_d = 0 drive: freeze motulator's field-weakening integrator (i_d ref stays 0, MTPA of
        # an SPM) and remove its flux-based torque cap (which assumes field weakening): the
        # current command is then simply i_q = clip(tau_ref / Kt, +-i_max).
        rcfg.k_fw = 0.0
        rcfg.lim_tau_M = lambda abs_psi_s: kt * i_max
    ctrl = control.CurrentVectorControl(par, rcfg, T_s=cfg["T_s"], alpha_c=cfg["alpha_c"], sensorless=False)
    if cfg["overmodulation"] == "linear":
        ctrl.pwm = _linear_pwm_class()()
    else:
        ctrl.pwm.overmodulation = cfg["overmodulation"]
    return model, mdl, ctrl


def simulate_point(req, cfg, w_M, tau_ref):
    """One run at imposed mechanical speed w_M with constant torque reference tau_ref."""
    n_p, psi = int(req["n_p"]), req["psi"]
    i_max = req["i_max"]
    t_stop = cfg["t_stop"]
    u_lim = req["u_dc"] / math.sqrt(3)
    kt = 1.5 * n_p * psi
    model, mdl, ctrl = _drive(req, cfg, w_M, bool(req["field_weakening"]))
    ctrl.ref.tau_M = lambda t: tau_ref

    sim = model.Simulation(mdl, ctrl)
    sim.simulate(t_stop=t_stop)

    d = mdl.machine.data
    t = d.t
    t0 = t_stop * (1 - cfg["window"])
    m = t >= t0
    tmid = 0.5 * (t0 + t[-1])
    tau = _twa(t, d.tau_M, m)
    tau_a = _twa(t, d.tau_M, m & (t < tmid))
    tau_b = _twa(t, d.tau_M, t >= tmid)
    i_s = _twa(t, d.i_s, m)  # continuous-time mean current, rotor frame
    u_s = d.u_ss * np.conj(d.exp_j_theta_m)  # realized converter voltage, rotor frame
    u_mean = _twa(t, u_s, m)  # its fundamental (dq mean)

    c = ctrl.data
    mc = c.ref.t >= t0
    ref_i = np.mean(c.ref.i_s[mc])
    meas_i = np.mean(c.fbk.i_s[mc])  # sampled current as the controller sees it
    abs_ref_u = np.abs(c.ref.u_s[mc])  # unlimited current-controller output
    track_err = abs(meas_i - ref_i)
    v_sat = float(np.mean(abs_ref_u > u_lim * (1 + SAT_TOL)))
    finite = bool(np.isfinite(tau)) and t[-1] >= t_stop * 0.999
    return {
        "tau": float(tau),
        "i_d": float(i_s.real),
        "i_q": float(i_s.imag),
        "i_d_ref": float(ref_i.real),
        "i_q_ref": float(ref_i.imag),
        "u_amplitude": float(abs(u_mean)),
        "u_ref_amplitude": float(np.mean(abs_ref_u)),
        "tracking_error": float(track_err),
        "voltage_saturated_fraction": v_sat,
        "held_control": bool(
            finite and track_err <= TRACK_TOL * i_max and v_sat == 0.0 and abs(i_s) <= (1 + OVER_TOL) * i_max
        ),
        "settled": bool(finite and abs(tau_b - tau_a) <= SETTLE_TOL * kt * i_max),
        "tau_drift": float(tau_b - tau_a),
    }


def _exact_mean_current(req, d, mask, w_e):
    """Exact time average of the rotor-frame current (and voltage) over the masked solver points.

    motulator's solver keeps only a few points per sampling period, so a trapezoid over them is
    close to the mean of the samples and misses the intra-period ripple (about 0.2 A in i_d on
    the sample motor). The converter voltage is piecewise constant in stator coordinates and the
    rotor angle is linear in time (imposed constant speed), so the mean rotor-frame voltage is
    integrated exactly. The machine equation u = R i + L di/dt + j w_e (L i + psi) (Ld = Lq = L)
    then gives the mean current exactly: i_mean = (u_mean - j w_e psi - L (i_end - i_start) / T)
    / (R + j w_e L).
    """
    R, L, psi = req["R"], req["L"], req["psi"]
    t, u_ss, ejth, i_s = d.t[mask], d.u_ss[mask], d.exp_j_theta_m[mask], d.i_s[mask]
    dt = np.diff(t)
    x = w_e * dt
    small = np.abs(x) < 1e-9
    # (1/dt) * integral over the segment of exp(-j theta), relative to its start value
    k = np.where(small, 1.0 + 0j, (1 - np.exp(-1j * x)) / (1j * np.where(small, 1.0, x)))
    seg = u_ss[:-1] * np.conj(ejth[:-1] / np.abs(ejth[:-1])) * k
    span = t[-1] - t[0]
    u_mean = np.sum(seg * dt) / span
    i_mean = (u_mean - 1j * w_e * psi - L * (i_s[-1] - i_s[0]) / span) / complex(R, w_e * L)
    return complex(i_mean), complex(u_mean)


class FixedCurrentReference:
    """Stands in for motulator's CurrentReference: the dq current reference is the constant i_ref.

    The torque reference and motulator's MTPA / field-weakening / torque-cap logic are bypassed;
    the current controller (with its anti-windup) and the PWM are motulator's.
    """

    def __init__(self, i_ref, kt):
        self.i_ref, self.kt = complex(i_ref), kt

    def output(self, fbk, ref):
        ref.i_s = self.i_ref
        ref.tau_M = self.kt * self.i_ref.imag  # the reference's torque (SPM), logged only
        return ref

    def update(self, fbk, ref):
        pass


def _start_at_reference(req, cfg, mdl, ctrl, w_M, i_ref):
    """Start the run in the ideal steady state of i_ref instead of at rest (zero current).

    Sets the machine flux to psi + L i_ref and, for the voltage u0 = (R + j w_e L) i_ref + j w_e psi
    (limited to u_dc/sqrt3), motulator's delay buffer, its PWM's realized-voltage memory and its
    current-controller integrator (u_i = u0 / sinc(w_e T_s / 2) + alpha_c L i_ref, the steady output
    with zero error). From rest, the back-EMF first drives the current far off (tens of A) and the
    saturated recovery near the voltage limit is slow (time constant L / (d|u|/di)); from here
    only the small discrete-time offsets remain to settle. These are motulator 0.5.0 internals.
    """
    R, L, psi, n_p, u_dc = req["R"], req["L"], req["psi"], int(req["n_p"]), req["u_dc"]
    u_lim = u_dc / math.sqrt(3)
    w_e, T_s = n_p * w_M, cfg["T_s"]
    x = 0.5 * w_e * T_s
    sinc = math.sin(x) / x if x else 1.0
    u0 = (complex(R, w_e * L) * i_ref + 1j * w_e * psi) / sinc
    u_cs = u0 * np.exp(1j * x)  # stator frame, the angle at the middle of the first period (theta(0) = 0)
    if abs(u_cs) > u_lim:
        u_cs *= u_lim / abs(u_cs)
    mdl.machine.state.psi_s = complex(psi + L * i_ref.real, L * i_ref.imag)
    mdl.delay.data = [list(ctrl.pwm.duty_ratios(u_cs, u_dc))]
    ctrl.pwm._old_u_cs = u_cs
    ctrl.pwm.realized_voltage = u_cs
    cc = ctrl.current_ctrl
    cc.u_i = u0 + (cc.k_p - cc.k_t) * L * i_ref


def simulate_reference(req, cfg, w_M, i_d, i_q):
    """One run at imposed mechanical speed w_M with the current reference fixed at i_d + j i_q."""
    import motulator.drive.control.sm  # noqa: F401  (imported before the timer: seconds is the run alone)

    t_run = time.time()
    n_p, psi, L = int(req["n_p"]), req["psi"], req["L"]
    i_max, t_stop, T_s, alpha_c = req["i_max"], cfg["t_stop"], cfg["T_s"], cfg["alpha_c"]
    u_lim = req["u_dc"] / math.sqrt(3)
    kt = 1.5 * n_p * psi
    model, mdl, ctrl = _drive(req, cfg, w_M, True)
    ctrl.current_reference = FixedCurrentReference(complex(i_d, i_q), kt)
    ctrl.ref.tau_M = lambda t: 0.0  # required by motulator's torque-control path; overwritten above
    if cfg["start"] == "steady":
        _start_at_reference(req, cfg, mdl, ctrl, w_M, complex(i_d, i_q))

    sim = model.Simulation(mdl, ctrl)
    sim.simulate(t_stop=t_stop)

    d = mdl.machine.data
    t = d.t
    # window: the last `window` fraction, cut to two halves of whole carrier periods (2 T_s) each, so
    # that the switching ripple (pwm "carrier") does not bias the half-window comparison
    n_half = max(1, int(cfg["window"] * t_stop / (4 * T_s)))
    t0 = t[-1] - 4 * n_half * T_s
    tmid = t[-1] - 2 * n_half * T_s
    eps = 1e-6 * T_s
    w_e = n_p * w_M
    i_s, _ = _exact_mean_current(req, d, t >= t0 - eps, w_e)
    i_a, _ = _exact_mean_current(req, d, (t >= t0 - eps) & (t <= tmid + eps), w_e)
    i_b, _ = _exact_mean_current(req, d, t >= tmid - eps, w_e)
    tau = kt * i_s.imag  # SPM (Ld = Lq): the torque is linear in i_q, so this is its exact mean

    c = ctrl.data
    mc = c.ref.t >= t0 - eps
    meas_i = np.mean(c.fbk.i_s[mc])  # sampled current as the controller sees it
    abs_ref_u = np.abs(c.ref.u_s[mc])  # unlimited current-controller output
    u_ratio = float(np.max(abs_ref_u) / u_lim)
    track_err = float(abs(meas_i - complex(i_d, i_q)))
    offset = float(np.mean(abs_ref_u)) * (w_e * T_s) ** 2 / (8 * alpha_c * L)
    tol = REF_TRACK_TOL * i_max + offset
    # ideal (continuous-time) voltage the reference needs, and the measured outward shift of the held edge
    u_ideal = abs(complex(req["R"], w_e * L) * complex(i_d, i_q) + 1j * w_e * psi) / u_lim
    edge_bias = (w_e * T_s) ** 2 * (1 / 24 + req["R"] / (8 * alpha_c * L))
    finite = bool(np.isfinite(i_s)) and bool(np.all(np.isfinite(abs_ref_u))) and t[-1] >= t_stop * 0.999
    return {
        "speed": float(w_M),
        "i_d_ref": float(i_d),
        "i_q_ref": float(i_q),
        "held_control": bool(finite and track_err <= tol and u_ratio <= 1.0),
        "torque": float(tau),
        "i_d": float(i_s.real),
        "i_q": float(i_s.imag),
        "u_ratio": u_ratio,
        "u_ratio_ideal": u_ideal,
        "edge_bias": edge_bias,
        "tracking_error": track_err,
        "tolerance": float(tol),
        "offset": offset,
        "current_ratio": float(abs(i_s) / i_max),
        "within_current_limit": bool(finite and abs(i_s) <= i_max + tol),
        "settled": bool(finite and abs(i_b - i_a) <= REF_SETTLE_TOL * i_max),
        "seconds": round(time.time() - t_run, 3),
    }


def closed_form(req):
    """Ideal steady state (no sampling, linear-range voltage u_dc/sqrt3): max and min i_q at each speed."""
    R, L, psi, n_p = req["R"], req["L"], req["psi"], int(req["n_p"])
    U, imax, fw = req["u_dc"] / math.sqrt(3), req["i_max"], bool(req["field_weakening"])
    kt = 1.5 * n_p * psi
    hi, lo = [], []
    for w in req["speeds"]:
        we = n_p * w
        if not fw:  # i_d = 0: (R iq + we psi)^2 + (we L iq)^2 <= U^2
            a, b, c0 = R * R + (we * L) ** 2, 2 * R * we * psi, (we * psi) ** 2 - U * U
            disc = b * b - 4 * a * c0
            if disc < 0:
                hi.append(None), lo.append(None)
                continue
            r1, r2 = (-b - math.sqrt(disc)) / (2 * a), (-b + math.sqrt(disc)) / (2 * a)
            top, bot = min(imax, r2), max(-imax, r1)
            if top < bot:
                hi.append(None), lo.append(None)
                continue
            hi.append(kt * top), lo.append(kt * bot)
            continue
        z = complex(R, we * L)
        c = -1j * we * psi / z
        r = U / abs(z)
        dist = abs(c)
        if dist > imax + r:
            hi.append(None), lo.append(None)
            continue
        cand = [1j * imax, -1j * imax, c + 1j * r, c - 1j * r]
        if dist > 0 and abs(imax - r) <= dist <= imax + r:  # circle-circle intersections
            a_ = (imax**2 - r**2 + dist**2) / (2 * dist)
            h = math.sqrt(max(imax**2 - a_**2, 0.0))
            e = c / dist
            p = a_ * e
            cand += [p + 1j * e * h, p - 1j * e * h]
        ok = [p for p in cand if abs(p) <= imax * (1 + 1e-9) and abs(p - c) <= r * (1 + 1e-9)]
        if not ok:
            hi.append(None), lo.append(None)
            continue
        hi.append(kt * max(p.imag for p in ok)), lo.append(kt * min(p.imag for p in ok))
    return hi, lo


def _job(args):
    return simulate_point(*args)


def _ref_job(args):
    return simulate_reference(*args)


def _map(fn, jobs, workers):
    if workers > 1 and len(jobs) > 1:
        with ProcessPoolExecutor(max_workers=workers) as ex:
            return list(ex.map(fn, jobs))
    return [fn(j) for j in jobs]


def _config(req):
    cfg = {k: req.get(k, v) for k, v in DEFAULTS.items()}
    if cfg["overmodulation"] not in ("linear", "MME", "MPE", "six_step"):
        raise SystemExit("overmodulation must be linear, MME, MPE or six_step")
    if cfg["pwm"] not in ("zoh", "carrier"):
        raise SystemExit("pwm must be zoh or carrier")
    return cfg


def main_references(req, t_wall):
    """references mode: is each fixed dq current reference held at its imposed speed? (schema /2)"""
    for k in ("R", "L", "psi", "n_p", "u_dc", "i_max", "points"):
        if k not in req:
            raise SystemExit(f"request lacks {k!r}")
    cfg = _config(req)
    cfg.update({k: req.get(k, v) for k, v in REF_DEFAULTS.items()})
    if cfg["start"] not in ("steady", "rest"):
        raise SystemExit("start must be steady or rest")
    if cfg["overmodulation"] != "linear":
        raise SystemExit("references mode needs overmodulation 'linear' (the limit tested is |u| <= u_dc/sqrt3)")
    jobs = []
    for p in req["points"]:
        if not all(k in p for k in ("speed", "i_d", "i_q")):
            raise SystemExit("each point needs speed, i_d and i_q")
        jobs.append((req, cfg, float(p["speed"]), float(p["i_d"]), float(p["i_q"])))
    workers = cfg["workers"] or min(2, os.cpu_count() or 1)
    res = _map(_ref_job, jobs, workers)
    u_lim = req["u_dc"] / math.sqrt(3)
    notes = [
        "Model: motulator.drive.model.Drive(VoltageSourceConverter(u_dc) stiff DC bus, "
        "SynchronousMachine(Ld=Lq=L, psi_f=psi, R_s=R), ExternalRotorSpeed(w_M const)).",
        "Control: motulator.drive.control.sm.CurrentVectorControl, sensored, "
        f"T_s={cfg['T_s']:g} s, alpha_c={cfg['alpha_c']:.1f} rad/s, one-sample computational delay, "
        "PWM delay compensation k_comp=1.5. Its current reference generator is replaced by "
        "FixedCurrentReference: the dq current reference is the point's i_d + j i_q throughout, with no "
        "torque reference, MTPA, field weakening or torque cap. motulator's current controller and its "
        "anti-windup are kept. "
        + (
            "start=steady: the run starts in the ideal steady state of the reference (machine flux, "
            "delay buffer, PWM memory and controller integrator set; motulator 0.5.0 internals). "
            if cfg["start"] == "steady"
            else "start=rest: the run starts at zero current. "
        )
        + f"{cfg['t_stop']:g} s per run. Averages are over the last {cfg['window']:.0%}, cut down to a whole "
        "number of 4 T_s, so that its two halves are whole carrier periods.",
        "Voltage limit: LinearRangePWM clips |u_ref| to u_limit = u_dc/sqrt3 after the delay "
        f"compensation (no overmodulation); PWM model {cfg['pwm']}.",
        "held_control: two conditions hold in the window. First, tracking_error = |mean sampled current - "
        f"reference| <= tolerance = {REF_TRACK_TOL:.1%} of i_max + offset. Second, u_ratio = max |u_ref| / "
        "u_limit <= 1, where u_ref is the unlimited current-controller output. offset = mean|u_ref| "
        "(w_e T_s)^2 / (8 alpha_c L) is motulator's steady discrete-time current error along u. The "
        "current limit is NOT part of held_control; see within_current_limit (|mean i| <= i_max + "
        "tolerance) and current_ratio = |mean i| / i_max.",
        "u_ratio_ideal = |(R + j w_e L) i_ref + j w_e psi| / u_limit is the continuous-time voltage the "
        "reference needs. motulator's drive holds a reference when u_ratio_ideal <= 1 + edge_bias, with "
        "edge_bias = (w_e T_s)^2 (1/24 + R / (8 alpha_c L)). This was measured by bisection on the sample "
        "motor, and it agrees to 0.001 % of voltage. Three terms make it up: (1) the ZOH voltage's "
        "fundamental is sinc(w_e T_s/2) times u_ref, which costs (w_e T_s)^2/24; (2) the controller "
        "regulates the current sampled at the start of each period, and the period-mean current is "
        "offset by j w_e T_s^2 u / (12 L), which saves (w_e T_s)^2/12 of voltage; (3) the steady error "
        "offset, which saves R offset / |u|. A reference analytically outside the voltage limit by less "
        "than edge_bias is therefore still held.",
        "torque, i_d, i_q: exact time averages over the window of the continuous-time rotor-frame current "
        "(computed from the exactly integrated mean voltage and the machine equation; a trapezoid over "
        "motulator's sparse solver points would only average the samples) and torque = 1.5 n_p psi i_q. "
        f"settled: the two half-window mean currents differ by <= {REF_SETTLE_TOL:.1%} of i_max. For "
        "points not held, the saturated loop can still drift slowly (time constant L / (d|u|/di)), so "
        "their averages and settled describe a transient. The decision does not depend on it. "
        "seconds: wall time of that point's run.",
    ]
    for k in ("alpha_fw", "k_u", "tau_ref", "overmodulation"):  # not used by this mode
        cfg.pop(k, None)
    out = {
        "schema": "motulator-check/2",
        "mode": "references",
        "motulator": version("motulator"),
        "request": {k: req[k] for k in req if k != "points"},
        "config": cfg,
        "u_limit": u_lim,
        "points": res,
        "notes": notes,
        "seconds": round(time.time() - t_wall, 2),
    }
    json.dump(out, sys.stdout, indent=1)
    sys.stdout.write("\n")


def main():
    t_wall = time.time()
    req = json.load(sys.stdin)
    mode = req.get("mode", "torque")
    if mode == "references":
        return main_references(req, t_wall)
    if mode != "torque":
        raise SystemExit("mode must be 'torque' (default) or 'references'")
    for k in ("R", "L", "psi", "n_p", "u_dc", "i_max", "field_weakening", "speeds"):
        if k not in req:
            raise SystemExit(f"request lacks {k!r}")
    cfg = _config(req)
    kt = 1.5 * int(req["n_p"]) * req["psi"]
    tau_ref = cfg["tau_ref"] if cfg["tau_ref"] is not None else 10 * kt * req["i_max"]
    cfg["tau_ref"] = tau_ref
    speeds = [float(w) for w in req["speeds"]]
    jobs = [(req, cfg, w, s * tau_ref) for w in speeds for s in (1.0, -1.0)]
    workers = cfg["workers"] or min(2, os.cpu_count() or 1)
    res = _map(_job, jobs, workers)
    up, dn = res[0::2], res[1::2]

    def both(key):
        return {"max": [r[key] for r in up], "min": [r[key] for r in dn]}

    cf_hi, cf_lo = closed_form(req)
    fw = bool(req["field_weakening"])
    notes = [
        "Model: motulator.drive.model.Drive(VoltageSourceConverter(u_dc) stiff DC bus, "
        "SynchronousMachine(Ld=Lq=L, psi_f=psi, R_s=R), ExternalRotorSpeed(w_M const)); "
        "the speed is imposed, so J is unused.",
        "Control: motulator.drive.control.sm.CurrentVectorControl, sensored (sensorless=False), "
        f"T_s={cfg['T_s']:g} s, alpha_c={cfg['alpha_c']:.1f} rad/s, one-sample computational "
        "delay (motulator default), PWM delay compensation k_comp=1.5, torque reference "
        f"+-{tau_ref:g} N m (torque-control mode), {cfg['t_stop']:g} s per run, averages over "
        f"the last {cfg['window']:.0%}.",
        (
            "field_weakening=true: motulator's CurrentReference (MTPA LUT = i_d 0 for an SPM; "
            "integral field-weakening loop on the unlimited voltage reference; torque cap from "
            "its merged MTPV/current-limit LUT at |psi_s| = k_u u_dc/sqrt3/|w_e|) with "
            f"k_u={cfg['k_u']:g}, alpha_fw={cfg['alpha_fw']:.1f} rad/s, max_i_s=i_max, "
            "nom_w_m = electrical no-load speed (sets k_fw = alpha_fw/(nom_w_m L)). Its torque "
            "cap is the current-circle torque at |psi_s| = k_u u_dc/sqrt3/|w_e|, the same for "
            "both signs, ignoring the R i drop; and its field-weakening integrator is clipped "
            "at the current-circle i_d of the capped torque. In motoring the cap allows points "
            "the bus cannot reach, i_d cannot go deeper than the clip, the voltage saturates "
            "and the current loop loses control (held_control false) from the true corner "
            "speed on; in braking it holds control but caps below what the bus allows. "
            "Compare with closed_form."
            if fw
            else "field_weakening=false: motulator has no i_d=0-with-voltage-limit reference "
            "generator; configured its CurrentReference with the field-weakening gain k_fw=0 "
            "(i_d ref stays 0) and its flux-based torque cap replaced by the constant 1.5 n_p "
            "psi i_max, so the command is i_q = +-i_max; the voltage limit is then enforced only "
            "by the PWM, with motulator's current-controller anti-windup (integrator fed the "
            "realized voltage). Where the bus cannot support the command the controller "
            "saturates and i_d drifts from 0 (held_control false); the torque reported is what "
            "that saturated loop achieves, not an ideal i_d=0 limit."
        ),
        (
            "Voltage limit: LinearRangePWM (a 10-line subclass of motulator's PWM) clips the "
            "voltage reference magnitude to u_dc/sqrt3 after motulator's delay compensation, so "
            "no overmodulation; the converter is otherwise motulator's (SVPWM min/max zero "
            "sequence)."
            if cfg["overmodulation"] == "linear"
            else f"Voltage limit: motulator's own PWM with overmodulation={cfg['overmodulation']}"
            " (duty ratios clipped to the hexagon): the fundamental can exceed u_dc/sqrt3 when "
            "saturated."
        ),
        f"PWM model: {cfg['pwm']} ("
        + (
            "duty ratios held over T_s, averaged switching"
            if cfg["pwm"] == "zoh"
            else "carrier comparison, switched voltages"
        )
        + "). The inverter switches are always modulated: motulator has no gate-off state, so "
        "uncontrolled diode rectification past the controllable speed is NOT represented; "
        "where held_control is false the torque is that of a saturated, still-switching drive.",
        "held_control: mean sampled current within 2 % of i_max of the (limited) reference, "
        "the unlimited voltage reference never above u_dc/sqrt3 (+0.1 %) and the mean current "
        "amplitude <= 1.02 i_max in the window. "
        "settled: the two halves of the window differ by <= 0.5 % of Kt i_max in torque.",
        "Discrete-time offset (motulator's controller, not the plant): its current-controller "
        "integrator is fed the 'realized' voltage 0.5 (u[k-1] + u[k]), whose magnitude is "
        "cos(w_e T_s / 2) times the controller output in steady rotation; the integrator then "
        "stops with a current error e = |u| (w_e T_s)^2 / (8 alpha_c L) along the voltage "
        "vector (tracking_error). At i_d = 0 the voltage is mostly along +q, so motoring "
        "|i_q| ends below and braking |i_q| above the reference (|i| slightly > i_max). It "
        "scales with T_s^2 / alpha_c.",
        "closed_form: ideal steady state with |u| <= u_dc/sqrt3, i_d=0 (field_weakening=false) "
        "or current circle and voltage disk intersection (true); null where infeasible.",
    ]
    u_lim = req["u_dc"] / math.sqrt(3)
    notes.append(
        f"R i_max / (u_dc/sqrt3) = {req['R'] * req['i_max'] / u_lim:.1%}: the share of the "
        "voltage limit taken by the resistive drop at full current, which motulator's flux-based "
        "torque cap and MTPV/current-limit LUTs ignore (relevant to field_weakening=true)."
    )
    out = {
        "schema": "motulator-check/1",
        "motulator": version("motulator"),
        "request": {k: req[k] for k in req if k != "speeds"},
        "config": cfg,
        "speeds": speeds,
        "max_torque": [r["tau"] for r in up],
        "min_torque": [r["tau"] for r in dn],
        "i_d": both("i_d"),
        "i_q": both("i_q"),
        "i_d_ref": both("i_d_ref"),
        "i_q_ref": both("i_q_ref"),
        "u_amplitude": both("u_amplitude"),
        "u_ref_amplitude": both("u_ref_amplitude"),
        "u_limit": req["u_dc"] / math.sqrt(3),
        "tracking_error": both("tracking_error"),
        "voltage_saturated_fraction": both("voltage_saturated_fraction"),
        "held_control": both("held_control"),
        "settled": both("settled"),
        "closed_form": {"max_torque": cf_hi, "min_torque": cf_lo},
        "notes": notes,
        "seconds": round(time.time() - t_wall, 2),
    }
    json.dump(out, sys.stdout, indent=1)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
