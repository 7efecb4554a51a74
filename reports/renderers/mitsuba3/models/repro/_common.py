"""Shared set-up of the reproduction scripts: Mitsuba 3.9.1 only (no furnace), one Dr.Jit thread
(the machine is shared). Directions follow furnace's model protocol: `wo` (viewer) is Mitsuba's
si.wi, `wi` (light) is Mitsuba's `wo` argument; local frame, z = normal."""
import os
import sys

os.environ.setdefault("DRJIT_LIBLLVM_PATH", "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1")
import numpy as np  # noqa: E402
import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402

EPS32 = float(np.finfo(np.float32).eps) / 2  # unit roundoff of float32, 5.96e-8


def setup(variant="llvm_ad_spectral"):
    mi.set_variant(variant)
    if dr.is_jit_v(mi.Float):
        dr.set_thread_count(1)
    return mi


def f32(a):
    """The float32 value of an f64 array (what Mitsuba receives), widened back to f64."""
    return np.asarray(a, dtype=np.float64).astype(np.float32).astype(np.float64)


def V(a):
    a = np.asarray(a, dtype=np.float64)
    return mi.Vector3f(*[mi.Float(np.ascontiguousarray(a[:, i]).astype(np.float32)) for i in range(3)])


def F(a):
    return mi.Float(np.ascontiguousarray(a).astype(np.float32))


def si_of(wo, wavelengths=(500.0, 550.0, 600.0, 650.0)):
    """SurfaceInteraction3f for a batch of viewer directions (protocol wo = Mitsuba si.wi)."""
    wo = np.asarray(wo, dtype=np.float64)
    n = wo.shape[0]
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = V(wo)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    si.n = mi.Normal3f(0, 0, 1)
    if mi.is_spectral:
        si.wavelengths = mi.Spectrum(*wavelengths)
    return si


def np3(v):
    """Mitsuba Vector3f (n lanes) -> numpy (n, 3) float64."""
    return np.array(v, dtype=np.float64).T


def np1(x):
    return np.array(x, dtype=np.float64).reshape(-1)


def spec0(s):
    """First wavelength lane of a Spectrum batch -> numpy (n,)."""
    return np.array(s, dtype=np.float64)[0]


def sample_bsdf(b, ctx, wo, u, uc):
    bs, w = b.sample(ctx, si_of(wo), F(uc), mi.Point2f(F(u[:, 0]), F(u[:, 1])))
    return np3(bs.wo), spec0(w), np1(bs.pdf), np.array(bs.sampled_type, dtype=np.int64)


def bsdf_pdf(b, ctx, wo, wi):
    return np1(b.pdf(ctx, si_of(wo), V(wi)))


def bsdf_fcos(b, ctx, wo, wi):
    """Mitsuba's eval: f(wo, wi)·|cos θ_wi| (first wavelength)."""
    return spec0(b.eval(ctx, si_of(wo), V(wi)))


def tiled(w, n):
    return np.tile(np.asarray(w, dtype=np.float64), (n, 1))


def ulp_neighbours(w):
    """w (float32 values) and its 6 neighbours one float32 ulp away in one component."""
    w32 = np.asarray(w, dtype=np.float64).astype(np.float32)
    out = [w32.astype(np.float64)]
    for k in range(3):
        for s in (-1, 1):
            x = w32.copy()
            x[:, k] = np.nextafter(x[:, k], np.float32(s * np.inf))
            out.append(x.astype(np.float64))
    return out


def header(title):
    print("=" * len(title))
    print(title)
    print("=" * len(title))
    print("mitsuba %s, variant %s, drjit %s, numpy %s" % (mi.__version__, mi.variant(), dr.__version__, np.__version__))
    sys.stdout.flush()


def chi2_sf(x, dof):
    """P(χ²_dof > x): the regularised upper incomplete gamma Q(dof/2, x/2), by its series or
    its continued fraction (Abramowitz & Stegun 6.5.29 and 6.5.31)."""
    from math import exp, lgamma, log
    a, z = dof / 2.0, x / 2.0
    if z <= 0:
        return 1.0
    if z < a + 1:
        term = s = 1.0 / a
        ap = a
        for _ in range(100000):
            ap += 1
            term *= z / ap
            s += term
            if abs(term) < abs(s) * 1e-15:
                break
        return max(0.0, 1.0 - s * exp(-z + a * log(z) - lgamma(a)))
    b = z + 1 - a; c = 1e300; d = 1 / b; h = d
    for i in range(1, 100000):
        an = -i * (i - a); b += 2
        d = an * d + b; d = 1e-300 if abs(d) < 1e-300 else d
        c = b + an / c; c = 1e-300 if abs(c) < 1e-300 else c
        d = 1 / d; delta = d * c; h *= delta
        if abs(delta - 1) < 1e-15:
            break
    return exp(-z + a * log(z) - lgamma(a)) * h


def chi2_gof(observed, expected, min_expected=5.0):
    """Pearson χ² with furnace's pooling (src/stats/chi2.rs): bins with expected < min_expected
    merged in ascending order, a remainder joining the smallest kept bin. Returns (χ², dof, p)."""
    obs = np.asarray(observed, dtype=np.float64); exp_ = np.asarray(expected, dtype=np.float64)
    keep = exp_ > 0
    if np.any(obs[~keep] > 0):
        return np.inf, 0, 0.0
    obs, exp_ = obs[keep], exp_[keep]
    small = exp_ < min_expected
    kept = list(zip(obs[~small], exp_[~small]))
    order = np.argsort(exp_[small]); so, se = obs[small][order], exp_[small][order]
    g = [0.0, 0.0]
    for o, e in zip(so, se):
        g[0] += o; g[1] += e
        if g[1] >= min_expected:
            kept.append(tuple(g)); g = [0.0, 0.0]
    if g[1] > 0:
        if kept:
            i = int(np.argmin([k[1] for k in kept])); kept[i] = (kept[i][0] + g[0], kept[i][1] + g[1])
        else:
            kept.append(tuple(g))
    o = np.array([k[0] for k in kept]); e = np.array([k[1] for k in kept])
    x2 = float(((o - e) ** 2 / e).sum()); dof = len(kept) - 1
    return x2, dof, chi2_sf(x2, dof)
