# Emulation of LuxCore PATHCPU for a lossless isotropic fog sphere (radius 1) behind a null boundary,
# env radiance 1, RR off, pathdepth.total = K+1, MIS NEE. The eye-path direction after a volume
# scatter is computed as LuxCore does, in float32 and never renormalised:
#   BSDF::Init(volume): geometryN = shadeN = Normal(-ray.d); CoordinateSystem(shadeN,&dpdu,&dpdv)
#   frame.SetFromZ(shadeN): Z = shadeN (not normalised), CoordinateSystem(Z, &X, &Y)
#   SchlickScatter::Sample: localFixedDir = frame.ToLocal(-ray.d); CoordinateSystem(localFixedDir,&x,&y)
#   dir = frame.ToWorld(SphericalDirection(sin,cos,2pi u1, x, y, localFixedDir)); eyeRay.Update(p, dir)
# and the free flight is sampled in ray-parameter units (Scatter: -log(1-u)/sigma compared with
# ray.maxt - ray.mint), so a direction of norm n makes the eye path see sigma/n.
# renorm=True normalises every direction (the unbiased reference).
import numpy as np, sys
f32 = np.float32
def cross(a, b):
    return np.stack([a[:,1]*b[:,2]-a[:,2]*b[:,1], a[:,2]*b[:,0]-a[:,0]*b[:,2], a[:,0]*b[:,1]-a[:,1]*b[:,0]], 1)
def dot(a, b): return a[:,0]*b[:,0] + a[:,1]*b[:,1] + a[:,2]*b[:,2]
def normalize(a):
    with np.errstate(all='ignore'):
        ln = np.sqrt(dot(a, a)); return a * (f32(1)/ln)[:, None]
def coordsys(v1):
    with np.errstate(all='ignore'):
        ln = np.sqrt(v1[:,0]*v1[:,0] + v1[:,1]*v1[:,1])
        small = ln < f32(1e-5)
        v3 = np.where(small[:, None], np.array([1, 0, 0], f32), np.stack([-v1[:,1]/ln, v1[:,0]/ln, np.zeros_like(ln)], 1)).astype(f32)
        v2 = cross(v1, v3)
    return v2, v3
def scatter_dir(d, rng):
    with np.errstate(all='ignore'):
        fixed = (-d).astype(f32); Z = fixed
        X, Y = coordsys(Z)   # BSDF::Init(volume): frame.SetFromZ(shadeN) -> CoordinateSystem(Z, &X, &Y)
        lfd = np.stack([dot(fixed, X), dot(fixed, Y), dot(fixed, Z)], 1).astype(f32)
        x, y = coordsys(lfd)
        u0 = rng.random(len(d)).astype(f32); u1 = rng.random(len(d)).astype(f32)
        cost = (-(f32(2)*u0 - f32(1))).astype(f32)
        sint = np.sqrt(np.maximum(f32(0), f32(1) - cost*cost))
        phi = (f32(2*np.pi)*u1).astype(f32)
        loc = ((sint*np.cos(phi))[:, None]*x + (sint*np.sin(phi))[:, None]*y + cost[:, None]*lfd).astype(f32)
        out = (X*loc[:, 0:1] + Y*loc[:, 1:2] + Z*loc[:, 2:3]).astype(f32)
    return out
def exit_t(p, d):  # parametric distance to the unit sphere from inside (d need not be unit)
    a = dot(d, d); b = dot(p, d); c = dot(p, p) - 1
    return (-b + np.sqrt(np.maximum(b*b - a*c, 0)))/a
def run(sigma, K, n=40000, renorm=False, seed=1):
    rng = np.random.default_rng(seed)
    t = np.tan(np.radians(15))
    sx = (rng.random(n)*8-4)/8*t; sy = (rng.random(n)*8-4)/8*t
    d0 = np.stack([sx, sy, np.ones(n)], 1); d0 /= np.linalg.norm(d0, axis=1)[:, None]
    o = np.tile([0, 0, -4.0], (n, 1))
    b = np.einsum('ij,ij->i', o, d0); c = np.einsum('ij,ij->i', o, o) - 1
    t1 = -b - np.sqrt(b*b - c); t2 = -b + np.sqrt(b*b - c)
    fl = -np.log1p(-rng.random(n))/sigma
    val = np.zeros(n); bad = np.zeros(n, bool); nverts = np.zeros(n, int)
    esc = fl >= (t2 - t1)
    val[esc] = 1.0  # camera ray through the fog: specular start, weight 1
    alive = ~esc
    p = o + d0*(t1 + fl)[:, None]
    d = d0.astype(f32)
    depth = 0
    while alive.any() and depth <= K:
        idx = np.nonzero(alive)[0]
        nverts[idx] += 1
        if depth == K:  # last vertex: no NEE, no continuation
            break
        pp = p[idx]
        # NEE: uniform direction, success with the true transmittance, MIS weight 1/2
        w = rng.normal(size=(idx.size, 3)); w /= np.linalg.norm(w, axis=1)[:, None]
        L = exit_t(pp, w)
        ok = rng.random(idx.size) < np.exp(-sigma*L)
        # NaN frame -> NaN radiance -> the film drops the whole sample
        nd = scatter_dir(d[idx], rng)
        if renorm:
            nd = (nd/np.linalg.norm(nd.astype(np.float64), axis=1)[:, None]).astype(f32)
        nan = ~np.isfinite(nd).all(1)
        bad[idx[nan]] = True
        val[idx] += 0.5*ok
        # continuation: free flight in parameter units
        nd64 = nd.astype(np.float64)
        with np.errstate(all='ignore'):
            tb = exit_t(pp, nd64)
            mint = 1e-5
            fl = -np.log1p(-rng.random(idx.size))/sigma
            skip = ~(tb > mint)              # exit hit closer than mint: missed -> trapped outside in "fog"
            scat = (fl < tb - mint) | skip
        e = ~scat & ~nan
        val[idx[e]] += 0.5
        alive[idx[e]] = False
        alive[idx[nan]] = False
        s = scat & ~nan
        j = idx[s]
        p[j] = pp[s] + nd64[s]*(mint + fl[s])[:, None]
        d[j] = nd[s]
        depth += 1
    val[bad] = 0.0
    long = nverts > K/2
    return val.mean(), val.std()/np.sqrt(n), long.mean(), bad.mean()
if __name__ == "__main__":
    for s, K in [(1, 1024), (2, 1024), (3, 1024), (4, 256), (4, 1024), (4, 2048), (8, 1024), (16, 1024)]:
        a = run(s, K); b = run(s, K, renorm=True)
        print(f"sigma {s:>2} K {K:>4}: emulated {a[0]:.3f} +- {a[1]:.3f} (long paths {a[2]:.4f}, NaN-dropped {a[3]:.4f})   renormalised {b[0]:.3f} +- {b[1]:.3f} (long {b[2]:.4f})")
