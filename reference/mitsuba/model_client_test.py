#!/usr/bin/env python3
"""A small client of furnace's model protocol (docs/model-protocol.md) that checks a model
server numerically: the Mitsuba 3 server next to this file (default) or any other server
(`--server CMD...`, e.g. the C example in protocol/). Standard library + numpy only.

    /work/venv-mitsuba/bin/python reference/mitsuba/model_client_test.py                # scalar_spectral
    DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 \
        /work/venv-mitsuba/bin/python reference/mitsuba/model_client_test.py --variant llvm_ad_spectral
    python3 reference/mitsuba/model_client_test.py --server /tmp/example_server      # the C example
    ... --bench 65536        # also time 65 536-query batches (queries/s per op)

Exit status 0 when every check passes (or when Mitsuba is not installed: the test is skipped
with a message), 1 when a check fails. The checks are this project's own verification of the
servers, not furnace's statistical suite: tolerances are for float32 renderers (Mitsuba).
"""

import argparse
import json
import math
import os
import struct
import subprocess
import sys
import time

try:
    import numpy as np
except ImportError:
    print("SKIP: numpy is not installed")
    sys.exit(0)

HERE = os.path.dirname(os.path.abspath(__file__))
LAMBDA = [380.0, 480.0, 580.0, 780.0]   # furnace's check_wavelengths() (harness catalogue)


class ServerError(Exception):
    pass


class Client:
    """One model server process, spoken to over stdin/stdout."""

    def __init__(self, argv, env=None):
        self.p = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                  env=env)

    def request(self, header, rows=None):
        if rows is not None:
            rows = np.ascontiguousarray(rows, dtype="<f8")
            header = dict(header, n=rows.shape[0], width=rows.shape[1])
        self.p.stdin.write(json.dumps(header).encode() + b"\n")
        if rows is not None:
            self.p.stdin.write(rows.tobytes())
        self.p.stdin.flush()
        line = self.p.stdout.readline()
        if not line:
            raise ServerError("server closed its stdout (exit status %s)" % self.p.poll())
        reply = json.loads(line)
        payload = None
        if "n" in reply:
            size = reply["n"] * reply["width"] * 8
            raw = self.p.stdout.read(size)
            if len(raw) != size:
                raise ServerError("short payload: %d of %d bytes" % (len(raw), size))
            payload = np.frombuffer(raw, dtype="<f8").reshape(reply["n"], reply["width"])
        return reply, payload

    def call(self, op, model, rows):
        reply, payload = self.request({"op": op, "model": model}, rows)
        if not reply.get("ok"):
            raise ServerError("%s %s: %s" % (op, model, reply.get("error")))
        return payload

    def close(self):
        try:
            self.p.stdin.write(b'{"op":"bye"}\n')
            self.p.stdin.flush()
            self.p.stdin.close()
        except (BrokenPipeError, OSError):
            pass
        try:
            return self.p.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.p.kill()
            return None


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------

class Report:
    def __init__(self):
        self.failed = 0
        self.passed = 0

    def check(self, ok, what, detail=""):
        print("%s  %s%s" % ("PASS" if ok else "FAIL", what, ("  (" + detail + ")") if detail else ""))
        if ok:
            self.passed += 1
        else:
            self.failed += 1
        return ok


def rng_dirs(rng, n, upper=True):
    """Uniform directions on the (upper) sphere (Archimedes: z uniform in [-1, 1])."""
    z = rng.uniform(0.0 if upper else -1.0, 1.0, n)
    phi = rng.uniform(0.0, 2.0 * math.pi, n)
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def wl_cols(n):
    return np.tile(np.array(LAMBDA), (n, 1))


def rel_err(a, b, floor=1e-30):
    return np.abs(a - b) / np.maximum(np.maximum(np.abs(a), np.abs(b)), floor)


def frame_around(axis):
    """Two unit vectors completing `axis` to an orthonormal frame (Duff et al. 2017, JCGT 6(1),
    'Building an Orthonormal Basis, Revisited', listing 3)."""
    x, y, z = axis
    s = math.copysign(1.0, z)
    a = -1.0 / (s + z)
    b = x * y * a
    return np.array([1.0 + s * x * x * a, s * b, -s * x]), np.array([b, s + y * y * a, -y])


# --------------------------------------------------------------------------------------------
# checks
# --------------------------------------------------------------------------------------------

def check_lambert(c, rep, model, rho, expect_pass=True):
    """eval = ρ/π at every pair of upper-hemisphere directions (Lambert 1760; furnace's
    Bxdf convention: no cosine)."""
    rng = np.random.default_rng(1)
    n = 2000
    q = np.concatenate([rng_dirs(rng, n), rng_dirs(rng, n), wl_cols(n)], axis=1)
    f = c.call("bsdf.eval", model, q)
    err = np.max(rel_err(f, rho / math.pi))
    ok = err < 1e-5
    what = "%s: eval == ρ/π = %.6g over %d pairs" % (model, rho / math.pi, n)
    if expect_pass:
        rep.check(ok, what, "max rel err %.2e" % err)
    else:
        rep.check(not ok, "negative control rejected: " + what,
                  "max rel err %.2e, mean f·π = %.4g" % (err, float(np.mean(f)) * math.pi))


def check_sample_weights(c, rep, model, lower=False, n=4000, tol=2e-3):
    """For every sample: weight == eval·|cos θi|/pdf and pdf == pdf(wo, wi) (furnace's
    sample-weight consistency, DESIGN.md "Conventions"); skips Dirac lobes and grazing rows
    (|cos| < 1e-2, where float32 rounding of the cosine dominates)."""
    rng = np.random.default_rng(7)
    wo = rng_dirs(rng, n, upper=not lower)
    u = rng.uniform(0.0, 1.0, (n, 3))
    s = c.call("bsdf.sample", model, np.concatenate([wo, u, wl_cols(n)], axis=1))
    flags = s[:, 8].astype(int)
    ok_rows = (flags & 1 == 1) & (flags & 2 == 0)
    wi, weight, pdf = s[:, 0:3], s[:, 3:7], s[:, 7]
    keep = ok_rows & (np.abs(wi[:, 2]) > 1e-2) & (np.abs(wo[:, 2]) > 1e-2) & (pdf > 1e-3)
    q = np.concatenate([wo[keep], wi[keep], wl_cols(int(keep.sum()))], axis=1)
    f = c.call("bsdf.eval", model, q)
    p = c.call("bsdf.pdf", model, q)[:, 0]
    expect = f * np.abs(wi[keep, 2:3]) / pdf[keep, None]
    # relative to the size of the weights, so that a near-zero lane does not dominate
    scale = np.maximum(np.abs(expect), np.abs(weight[keep])).max(axis=1, keepdims=True) + 1e-12
    e_w = np.max(np.abs(weight[keep] - expect) / scale) if keep.any() else 0.0
    e_p = np.max(rel_err(p, pdf[keep])) if keep.any() else 0.0
    side = "wo below" if lower else "wo above"
    rep.check(keep.sum() > n // 10 and e_w < tol and e_p < tol,
              "%s (%s): weight == eval·|cos|/pdf, pdf == pdf(wo,wi)" % (model, side),
              "%d of %d samples used, %d no-sample; max rel err weight %.2e, pdf %.2e"
              % (keep.sum(), n, int((flags == 0).sum()), e_w, e_p))


def check_reciprocity(c, rep, model, eta):
    """f(wo,wi)/η(wo)² == f(wi,wo)/η(wi)² (Veach 1997, §5.2, eq. 5.21), η(w) = eta below."""
    rng = np.random.default_rng(3)
    n = 3000
    a = rng_dirs(rng, n, upper=False)
    b = rng_dirs(rng, n, upper=False)
    keep = (np.abs(a[:, 2]) > 0.05) & (np.abs(b[:, 2]) > 0.05)
    a, b = a[keep], b[keep]
    m = a.shape[0]
    f_ab = c.call("bsdf.eval", model, np.concatenate([a, b, wl_cols(m)], axis=1))[:, 0]
    f_ba = c.call("bsdf.eval", model, np.concatenate([b, a, wl_cols(m)], axis=1))[:, 0]
    ea = np.where(a[:, 2] > 0, 1.0, eta) ** 2
    eb = np.where(b[:, 2] > 0, 1.0, eta) ** 2
    lhs, rhs = f_ab / ea, f_ba / eb
    big = np.maximum(lhs, rhs) > 1e-3 * max(np.max(lhs), 1e-30)
    err = np.max(rel_err(lhs[big], rhs[big])) if big.any() else 0.0
    rep.check(err < 1e-3, "%s: f(wo,wi)/η(wo)² == f(wi,wo)/η(wi)²" % model,
              "%d pairs, max rel err %.2e" % (int(big.sum()), err))


def check_mirror(c, rep, model):
    """A perfect mirror's sample is the mirror direction (-x, -y, z) with weight 1."""
    rng = np.random.default_rng(5)
    n = 500
    wo = rng_dirs(rng, n)
    s = c.call("bsdf.sample", model,
               np.concatenate([wo, rng.uniform(0, 1, (n, 3)), wl_cols(n)], axis=1))
    mirror = wo * np.array([-1.0, -1.0, 1.0])
    e_d = np.max(np.abs(s[:, 0:3] - mirror))
    e_w = np.max(np.abs(s[:, 3:7] - 1.0))
    flags_ok = np.all(s[:, 8] == 3.0)
    f = c.call("bsdf.eval", model, np.concatenate([wo, mirror, wl_cols(n)], axis=1))
    p = c.call("bsdf.pdf", model, np.concatenate([wo, mirror, wl_cols(n)], axis=1))
    rep.check(e_d < 1e-6 and e_w < 1e-6 and flags_ok and not f.any() and not p.any(),
              "%s: sample = mirror direction, weight 1, flags 1|2, eval = pdf = 0" % model,
              "max |Δwi| %.1e, max |weight − 1| %.1e, pdf column %s"
              % (e_d, e_w, np.unique(s[:, 7])[:3]))


def check_lossless(c, rep, model, eta, two_sided_or_transmissive, n=20000):
    """A lossless model scatters all power: the mean of weight·η(wi)²/η(wo)² over samples is 1
    at every angle (Veach 1997, §5.2: radiance weights carry 1/η² across refraction), where
    η(w) = 1 above the surface and the `eta` flag below."""
    rng = np.random.default_rng(19)
    worst = 0.0
    detail = []
    sides = (1.0, -1.0) if two_sided_or_transmissive else (1.0,)
    for side in sides:
        for theta in (0.0, 45.0, 80.0, 89.0):
            t = math.radians(theta)
            wo = np.array([math.sin(t), 0.0, side * math.cos(t)])
            q = np.concatenate([np.tile(wo, (n, 1)), rng.uniform(0, 1, (n, 3)), wl_cols(n)], 1)
            s = c.call("bsdf.sample", model, q)
            ok = s[:, 8] != 0
            eta_o = 1.0 if wo[2] > 0 else eta
            eta_i = np.where(s[:, 2] > 0, 1.0, eta)
            power = np.where(ok, s[:, 3] * (eta_i / eta_o) ** 2, 0.0)
            m, se = power.mean(), power.std(ddof=1) / math.sqrt(n)
            worst = max(worst, abs(m - 1.0) / (4.0 * se + 1e-5))
            detail.append("%+.0f°: %.5f±%.5f" % (side * theta, m, se))
    rep.check(worst < 1.0, "%s: lossless, mean weight·η(wi)²/η(wo)² = 1" % model,
              ", ".join(detail))


def check_sidedness(c, rep, models, n=1000):
    """The `two_sided` flag: a two-sided model answers for wo, wi below the surface as for
    their mirror images above; a one-sided reflector answers 0 there."""
    rng = np.random.default_rng(23)
    wo, wi = rng_dirs(rng, n), rng_dirs(rng, n)
    flip = np.array([1.0, 1.0, -1.0])
    up = np.concatenate([wo, wi, wl_cols(n)], 1)
    down = np.concatenate([wo * flip, wi * flip, wl_cols(n)], 1)
    bad = []
    for m in models:
        fl = m["flags"]
        if m["kind"] != "bsdf" or (fl["transmission"] and not fl["two_sided"]):
            continue
        f_up = c.call("bsdf.eval", m["name"], up)
        f_down = c.call("bsdf.eval", m["name"], down)
        if fl["two_sided"]:
            if np.max(rel_err(f_up, f_down)) > 1e-6:
                bad.append(m["name"] + " (two_sided but differs below)")
        elif f_down.any():
            bad.append(m["name"] + " (one-sided but answers below)")
    rep.check(not bad, "two_sided flags agree with eval below the surface",
              "; ".join(bad) if bad else "")


def phase_integral(c, model, g, wo):
    """∫ p(wo, wi) dωi by Gauss–Legendre in μ (graded towards μ = 1 for peaked lobes) times
    the trapezoid rule in φ, around the forward axis −wo."""
    t1, t2 = frame_around(-wo)
    # μ = 1 − 2·x^k on x in [0,1]: clusters nodes near forward scattering (k = 4 for |g| > .5)
    k = 4 if abs(g) > 0.5 else 1
    x, w = np.polynomial.legendre.leggauss(400)
    x = 0.5 * (x + 1.0)
    w = 0.5 * w
    results = []
    for sign in (1.0, -1.0):     # graded towards forward (+1) and backward (−1) halves
        mu = sign * (1.0 - x ** k)
        dmu = k * x ** (k - 1)
        nphi = 16
        phis = 2.0 * math.pi * (np.arange(nphi) + 0.5) / nphi
        MU, PHI = np.meshgrid(mu, phis, indexing="ij")
        s = np.sqrt(np.maximum(0.0, 1.0 - MU ** 2))
        d = (MU[..., None] * (-wo) + s[..., None] * np.cos(PHI)[..., None] * t1
             + s[..., None] * np.sin(PHI)[..., None] * t2).reshape(-1, 3)
        q = np.concatenate([np.tile(wo, (d.shape[0], 1)), d, wl_cols(d.shape[0])], axis=1)
        p = c.call("phase.pdf", model, q)[:, 0].reshape(MU.shape)
        results.append(np.sum(p.mean(axis=1) * 2.0 * math.pi * w * dmu))
    return sum(results)   # forward half μ in [0, 1] plus backward half μ in [-1, 0]


def check_phase(c, rep, model, g, n=20000):
    wo = np.array([0.3, -0.2, 0.9])
    wo /= np.linalg.norm(wo)
    total = phase_integral(c, model, g, wo)
    rep.check(abs(total - 1.0) < 2e-4, "%s: ∫ pdf dω = 1" % model, "%.6f" % total)
    # eval == pdf for these exactly sampled phase functions; and the sample's pdf is pdf(wo, wi)
    rng = np.random.default_rng(11)
    u = rng.uniform(0.0, 1.0, (n, 2))
    s = c.call("phase.sample", model, np.concatenate([np.tile(wo, (n, 1)), u, wl_cols(n)], axis=1))
    wi = s[:, 0:3]
    q = np.concatenate([np.tile(wo, (n, 1)), wi, wl_cols(n)], axis=1)
    pe = c.call("phase.eval", model, q)[:, 0]
    pp = c.call("phase.pdf", model, q)[:, 0]
    e_ep = np.max(rel_err(pe, pp))
    e_sp = np.median(rel_err(s[:, 4], pp))
    e_w = np.max(np.abs(s[:, 3] - pe / pp))
    rep.check(e_ep < 1e-6 and e_w < 1e-4 and e_sp < 1e-3,
              "%s: eval == pdf, sample weight == p/pdf, sample pdf == pdf(wo,wi)" % model,
              "max rel |eval−pdf| %.1e, median rel |pdf_sample − pdf| %.1e, max rel %.1e"
              % (e_ep, e_sp, np.max(rel_err(s[:, 4], pp))))
    # sign convention: mean scattering cosine −wo·wi must be g (forward scattering for g > 0)
    mu = -(wi @ wo)
    mean, se = mu.mean(), mu.std(ddof=1) / math.sqrt(n)
    rep.check(abs(mean - g) < 4.0 * se + 1e-4, "%s: mean of −wo·wi over samples = g = %g" % (model, g),
              "%.5f ± %.5f" % (mean, se))


def check_hg_peak(c, rep, model, g, n=20000):
    """Not a pass/fail check: prints HG at its peak against (1+|g|)/(4π(1−|g|)²) (Henyey &
    Greenstein 1941, eq. 3 at μ = ±1) and counts non-finite sample pdfs. At |g| → 1 a float32
    1 + g² − 2|g| cancels (DESIGN.md, "Known pitfalls")."""
    wo = np.array([0.0, 0.0, 1.0])
    peak = -wo if g > 0 else wo          # forward for g > 0, backward for g < 0
    q = np.concatenate([wo, peak, LAMBDA])[None, :]
    p = c.call("phase.eval", model, q)[0, 0]
    a = abs(g)
    exact = (1.0 + a) / (4.0 * math.pi * (1.0 - a) ** 2)
    rng = np.random.default_rng(29)
    s = c.call("phase.sample", model, np.concatenate(
        [np.tile(wo, (n, 1)), rng.uniform(0, 1, (n, 2)), wl_cols(n)], axis=1))
    bad = int((~np.isfinite(s[:, 4])).sum())
    print("INFO  %s: p at the peak = %.6g, exact %.6g; %d of %d sample pdfs non-finite"
          % (model, p, exact, bad, n))


def sphere_cone_pdf(center, radius, p):
    """Uniform-cone pdf of the directions subtending a sphere seen from outside:
    1/(2π(1 − cos θmax)), 1 − cos θmax = s/(1 + √(1 − s)), s = (r/d)² (DESIGN.md, stable form)."""
    d2 = float(np.sum((np.array(center) - np.array(p)) ** 2))
    s = radius * radius / d2
    return 1.0 / (2.0 * math.pi * s / (1.0 + math.sqrt(1.0 - s)))


def triangle_solid_angle(p, a, b, c):
    """Solid angle of triangle abc seen from p (Van Oosterom & Strackee 1983, IEEE Trans.
    Biomed. Eng. 30(2), eq. 8): tan(Ω/2) = |a·(b×c)| / (abc + (a·b)c + (a·c)b + (b·c)a)."""
    a, b, c = (np.array(v, dtype=float) - p for v in (a, b, c))
    la, lb, lc = (np.linalg.norm(v) for v in (a, b, c))
    num = abs(a @ np.cross(b, c))
    den = la * lb * lc + (a @ b) * lc + (a @ c) * lb + (b @ c) * la
    return 2.0 * math.atan2(num, den)


def emitter_solid_angle(par, p):
    """Closed-form solid angle of the emitter seen from p (None when not known here)."""
    if par["type"] == "constant":
        return 4.0 * math.pi
    if par["shape"] == "sphere":
        if par.get("emits") == "inwards":
            return 4.0 * math.pi
        d2 = float(np.sum((np.array(par["center"]) - p) ** 2))
        s = par["radius"] ** 2 / d2
        return 2.0 * math.pi * s / (1.0 + math.sqrt(1.0 - s))   # 2π(1 − cos θmax), stable
    if par["shape"] == "parallelogram":
        o, eu, ev = (np.array(par[k]) for k in ("corner", "edge_u", "edge_v"))
        return (triangle_solid_angle(p, o, o + eu, o + eu + ev)
                + triangle_solid_angle(p, o, o + eu + ev, o + ev))
    if par["shape"] == "triangles":
        v = par["vertices"]
        return sum(triangle_solid_angle(p, v[f[0]], v[f[1]], v[f[2]]) for f in par["faces"])
    return None


def check_emitter_unbiased(c, rep, models, n=100000):
    """The sampler and its pdf together are unbiased: mean(radiance/pdf) = L·Ω, the emitter's
    radiance times its closed-form solid angle (a Monte Carlo estimate of ∫ L dω)."""
    rng = np.random.default_rng(31)
    for m in models:
        if m["kind"] != "emitter" or m["flags"].get("delta"):
            continue
        par = m["params"]
        p = np.array(par.get("p", [0.0, 0.0, 0.0]))
        omega = emitter_solid_angle(par, p)
        if omega is None:
            continue
        q = np.concatenate([np.tile(p, (n, 1)), rng.uniform(0, 1, (n, 3)), wl_cols(n)], axis=1)
        s = c.call("emitter.sample_direction", m["name"], q)
        x = np.where(s[:, 9] != 0, s[:, 3] / np.where(s[:, 7] > 0, s[:, 7], 1.0), 0.0)
        mean, se = x.mean(), x.std(ddof=1) / math.sqrt(n)
        expect = par["radiance"] * omega
        rep.check(abs(mean - expect) < 4.0 * se + 1e-6 * expect,
                  "%s: mean radiance/pdf = L·Ω = %.6f" % (m["name"], expect),
                  "%.6f ± %.6f (%s)" % (mean, se, "%+.2f σ" % ((mean - expect) / se) if se > 0
                                         else "rel err %.1e" % (abs(mean - expect) / expect)))


def check_emitters(c, rep, models, n=4000):
    rng = np.random.default_rng(13)
    by_name = {m["name"]: m for m in models}
    for name, m in by_name.items():
        if m["kind"] != "emitter":
            continue
        par = m["params"]
        p = np.array(par.get("p", [0.0, 0.0, 0.0]))
        L = par.get("radiance", None)
        q = np.concatenate([np.tile(p, (n, 1)), rng.uniform(0, 1, (n, 3)), wl_cols(n)], axis=1)
        s = c.call("emitter.sample_direction", name, q)
        fl = s[:, 9].astype(int)
        ok = fl != 0
        wi, rad, pdf, dist = s[:, 0:3], s[:, 3:7], s[:, 7], s[:, 8]
        pq = np.concatenate([np.tile(p, (n, 1)), wi, wl_cols(n)], axis=1)
        pdf2 = c.call("emitter.pdf_direction", name, pq)[:, 0]
        if par["type"] == "point":
            pos = np.array(par["position"])
            d2 = np.sum((pos - p) ** 2)
            dirn = (pos - p) / math.sqrt(d2)
            e = np.max(rel_err(rad, par["intensity"] / d2))
            rep.check(np.all(fl == 3) and e < 1e-5 and np.max(np.abs(wi - dirn)) < 1e-6
                      and np.all(pdf == 1.0) and not pdf2.any(),
                      "%s: wi towards the light, radiance column = I/d², pdf 1, flags 1|2, "
                      "pdf_direction 0" % name, "max rel err %.1e" % e)
            continue
        e_L = np.max(rel_err(rad[ok], L))
        e_p = np.max(rel_err(pdf[ok], pdf2[ok]))
        detail = "%d/%d samples, max rel err radiance %.1e, pdf vs pdf_direction %.1e" % (
            ok.sum(), n, e_L, e_p)
        good = ok.all() and e_L < 1e-5 and e_p < 1e-3
        if par["type"] == "constant":
            good &= np.all(np.isinf(dist)) and np.max(rel_err(pdf, 1.0 / (4.0 * math.pi))) < 1e-6
            detail += ", dist ∞, pdf 1/4π"
        elif par["shape"] == "sphere" and par.get("emits") == "outwards":
            cone = sphere_cone_pdf(par["center"], par["radius"], p)
            e_c = np.max(rel_err(pdf[ok], cone))
            good &= e_c < 1e-4
            detail += ", pdf vs cone pdf %.1e" % e_c
        elif par["shape"] == "parallelogram":
            # independent: pdf = d²/(|cos θl| A) for the uniform area sampler (PBR 3rd ed. eq. 14.7)
            eu, ev = np.array(par["edge_u"]), np.array(par["edge_v"])
            nrm = np.cross(eu, ev)
            A = np.linalg.norm(nrm)
            nrm /= A
            d = dist[ok]
            expect = d * d / (np.abs(wi[ok] @ nrm) * A)
            e_a = np.max(rel_err(pdf[ok], expect))
            # the sampled point lies on the parallelogram
            x = p + wi[ok] * d[:, None] - np.array(par["corner"])
            G = np.array([[eu @ eu, eu @ ev], [eu @ ev, ev @ ev]])
            st = np.linalg.solve(G, np.stack([x @ eu, x @ ev]))
            inside = np.all((st > -1e-5) & (st < 1 + 1e-5)) and np.max(np.abs(x @ nrm)) < 1e-5
            good &= e_a < 1e-4 and inside
            detail += ", pdf vs d²/(|cos|A) %.1e, points on the parallelogram: %s" % (e_a, inside)
        rep.check(good, "%s: radiance = %s, pdf == pdf_direction(wi)" % (name, L), detail)


def check_errors(c, rep, models):
    name = next(m["name"] for m in models if m["kind"] == "bsdf")
    r, _ = c.request({"op": "bsdf.nonsense", "model": name})
    rep.check(r.get("ok") is False and "unknown op" in r.get("error", ""),
              "unknown op answers ok:false 'unknown op ...'", r.get("error", ""))
    r, _ = c.request({"op": "bsdf.eval", "model": name}, np.zeros((2, 9)))
    rep.check(r.get("ok") is False, "wrong row width answers ok:false", r.get("error", ""))
    r, _ = c.request({"op": "bsdf.eval", "model": "no such model"}, np.zeros((1, 10)))
    rep.check(r.get("ok") is False, "unknown model answers ok:false", r.get("error", ""))
    r, p = c.request({"op": "bsdf.eval", "model": name}, np.zeros((0, 10)))
    rep.check(r.get("ok") is True and r.get("n") == 0 and r.get("width") == 4,
              "empty batch answers n=0, width=4", json.dumps(r))


def bench(c, models, n):
    """Queries/s per op on one model of each kind, 3 batches of n (after one warm-up batch,
    which for llvm variants includes the kernel compilation)."""
    rng = np.random.default_rng(17)
    names = {m["kind"]: m["name"] for m in reversed(models)}
    pick = {"bsdf": "conductor/ggx α=0.3 perfect", "phase": "hg g=0.5", "emitter": "area rectangle"}
    for k, v in pick.items():
        if any(m["name"] == v for m in models):
            names[k] = v
    wo = rng_dirs(rng, n)
    wi = rng_dirs(rng, n)
    u = rng.uniform(0, 1, (n, 3))
    wl = wl_cols(n)
    reqs = [("bsdf.eval", names.get("bsdf"), np.concatenate([wo, wi, wl], 1)),
            ("bsdf.pdf", names.get("bsdf"), np.concatenate([wo, wi, wl], 1)),
            ("bsdf.sample", names.get("bsdf"), np.concatenate([wo, u, wl], 1)),
            ("phase.eval", names.get("phase"), np.concatenate([wo, wi, wl], 1)),
            ("phase.sample", names.get("phase"), np.concatenate([wo, u[:, :2], wl], 1)),
            ("emitter.sample_direction", names.get("emitter"),
             np.concatenate([np.zeros((n, 3)), u, wl], 1)),
            ("emitter.pdf_direction", names.get("emitter"),
             np.concatenate([np.zeros((n, 3)), wi * np.array([1, 1, 1]), wl], 1))]
    for op, model, q in reqs:
        if model is None:
            continue
        t0 = time.perf_counter()
        c.call(op, model, q)
        warm = time.perf_counter() - t0
        t0 = time.perf_counter()
        for _ in range(3):
            c.call(op, model, q)
        dt = (time.perf_counter() - t0) / 3
        print("BENCH %-26s %-32s n=%d  %10.0f queries/s  (first batch %.2f s)"
              % (op, model, n, n / dt, warm))


# --------------------------------------------------------------------------------------------

def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--variant", default="scalar_spectral")
    ap.add_argument("--server", nargs=argparse.REMAINDER,
                    help="another server's argv (the rest of the command line)")
    ap.add_argument("--bench", type=int, default=0, metavar="N",
                    help="also time batches of N queries")
    ap.add_argument("--quick", action="store_true", help="fewer checks (for scalar variants)")
    args = ap.parse_args()

    if args.server:
        argv = args.server
    else:
        probe = subprocess.run([sys.executable, "-c", "import mitsuba"], capture_output=True)
        if probe.returncode != 0:
            print("SKIP: mitsuba is not installed for %s (pip install mitsuba numpy in a venv "
                  "and run this script with that venv's python)" % sys.executable)
            return 0
        argv = [sys.executable, os.path.join(HERE, "model_server.py"), "--variant", args.variant]

    c = Client(argv)
    rep = Report()
    try:
        t0 = time.perf_counter()
        hello, _ = c.request({"op": "hello", "protocol": 1})
        print("hello: %s %s, %d models (%.2f s)" % (hello.get("renderer"), hello.get("version"),
                                                  len(hello.get("models", [])),
                                                  time.perf_counter() - t0))
        rep.check(hello.get("ok") is True and hello.get("protocol") == 1, "hello: protocol 1")
        models = hello["models"]
        names = {m["name"] for m in models}
        if len(names) != len(models):
            rep.check(False, "model names are unique")
        check_errors(c, rep, models)

        if "diffuse/0.5" in names:
            check_lambert(c, rep, "diffuse/0.5", 0.5)
        if "diffuse/0.5 without 1/pi" in names:
            check_lambert(c, rep, "diffuse/0.5 without 1/pi", 0.5, expect_pass=False)
        weight_models = [("diffuse/0.5", False), ("diffuse/0", False),
                         ("conductor/ggx α=0.3 perfect", False),
                         ("conductor/ggx αx=0.1 αy=0.5", False),
                         ("conductor/beckmann α=0.3 perfect", False),
                         ("conductor/ggx α=0.3 perfect, sample_visible=false", False),
                         ("dielectric/ggx α=0.5 η=1.5", False), ("dielectric/ggx α=0.5 η=1.5", True),
                         ("dielectric/beckmann α=0.3 η=1.5", True),
                         ("plastic/roughplastic ggx α=0.1 η=1.5", False),
                         ("principled/base 0.5 roughness 0.5", False),
                         ("principled/spec_trans 1 roughness 0.3 η=1.5", False),
                         ("twosided/diffuse 0.5", True),
                         ("blendbsdf/0.3 diffuse 0.5 + 0.7 conductor ggx α=0.3 perfect", False)]
        if args.quick:
            weight_models = weight_models[:3]
        for m, lower in weight_models:
            if m in names:
                check_sample_weights(c, rep, m, lower=lower)
        if "diffuse/0.5 without 1/pi" in names:
            check_sample_weights(c, rep, "diffuse/0.5 without 1/pi")
        for m in ["dielectric/ggx α=0.5 η=1.5", "dielectric/beckmann α=0.3 η=1.5",
                  "principled/spec_trans 1 roughness 0.3 η=1.5"]:
            if m in names and not args.quick:
                check_reciprocity(c, rep, m, 1.5)
        if "conductor/smooth perfect" in names:
            check_mirror(c, rep, "conductor/smooth perfect")
        check_sidedness(c, rep, models)
        for m in models:
            fl = m["flags"]
            if m["kind"] == "bsdf" and fl.get("lossless") and not args.quick:
                check_lossless(c, rep, m["name"], fl["eta"],
                               fl["two_sided"] or fl["transmission"])
        for m in models:
            if m["kind"] != "phase":
                continue
            g = m["flags"].get("mean_cosine")
            if args.quick and m["name"] not in ("hg g=0.5", "hg g=-0.3"):
                continue
            if g is not None and abs(g) < 0.95:
                check_phase(c, rep, m["name"], g)
            elif g is not None and m["name"].startswith("hg"):
                check_hg_peak(c, rep, m["name"], g)
        if not args.quick or any(m["kind"] == "emitter" for m in models):
            check_emitters(c, rep, models, n=1000 if args.quick else 4000)
            check_emitter_unbiased(c, rep, models, n=20000 if args.quick else 100000)
        if args.bench:
            bench(c, models, args.bench)
    except ServerError as e:
        rep.check(False, "server answered", str(e))
    finally:
        status = c.close()
    rep.check(status == 0, "server exits 0 after bye", "status %s" % status)
    print("%d passed, %d failed" % (rep.passed, rep.failed))
    return 1 if rep.failed else 0


if __name__ == "__main__":
    sys.exit(main())
