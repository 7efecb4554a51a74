# Monte Carlo emulation of LuxCore PATHCPU on "fog sphere inside glass" (radius 1, env radiance 1,
# lossless isotropic fog sigma, ior n), following Scene::Intersect + GlassMaterial::Sample:
# the same passThrough u decides the free flight in the segment ending at the glass AND, via
# hitPoint.passThroughEvent, the glass reflect/transmit choice (transmit iff u < threshold).
# correlated=False draws an independent u for the glass choice (the unbiased reference).
import numpy as np, sys
def fresnel(cosi, eta):  # FresnelTexture::CauchyEvaluate(eta=nt/nc, cosi) (dielectric)
    entering = cosi > 0
    e2 = eta*eta
    sint2 = np.where(entering, 1/e2, e2) * np.maximum(0, 1-cosi*cosi)
    tir = sint2 >= 1
    cost = np.sqrt(np.maximum(0, 1-sint2)); ci = np.abs(cosi)
    et = np.where(entering, eta, 1/eta)
    rpar = (cost - et*ci)/(cost + et*ci); rperp = (ci - et*cost)/(ci + et*cost)
    return np.where(tir, 1.0, 0.5*(rpar**2 + rperp**2)), tir
def run(sigma, ior, correlated, n=200000, K=64, seed=1):
    rng = np.random.default_rng(seed)
    # camera at z=-4 looking +z, rays within the central 8x8 of a 16x16 image, fov 30
    t = np.tan(np.radians(15))
    sx = (rng.random(n)*8 - 4)/8*t; sy = (rng.random(n)*8 - 4)/8*t
    d = np.stack([sx, sy, np.ones(n)], 1); d /= np.linalg.norm(d, axis=1)[:, None]
    o = np.tile([0, 0, -4.0], (n, 1))
    val = np.zeros(n); w = np.ones(n); alive = np.ones(n, bool); inside = np.zeros(n, bool)
    depth = np.zeros(n, int)
    for step in range(4*K):
        idx = np.nonzero(alive)[0]
        if idx.size == 0: break
        oo, dd = o[idx], d[idx]
        b = np.einsum('ij,ij->i', oo, dd); c = np.einsum('ij,ij->i', oo, oo) - 1
        disc = b*b - c
        hit = disc > 0
        tb = np.where(inside[idx], -b + np.sqrt(np.maximum(disc, 0)), -b - np.sqrt(np.maximum(disc, 0)))
        hit &= tb > 1e-7
        # misses: escape (only from outside)
        miss = ~hit
        val[idx[miss]] += w[idx[miss]]; alive[idx[miss]] = False
        idx, tb, oo, dd = idx[hit], tb[hit], oo[hit], dd[hit]
        u = rng.random(idx.size)
        ins = inside[idx]
        # free flight inside the fog
        fl = -np.log1p(-u)/sigma
        sc = ins & (fl < tb)
        # volume scatter vertices
        j = idx[sc]
        o[j] = oo[sc] + dd[sc]*fl[sc][:, None]
        v = rng.normal(size=(j.size, 3)); d[j] = v/np.linalg.norm(v, axis=1)[:, None]
        depth[j] += 1
        # glass vertices
        g = ~sc; j = idx[g]
        p = oo[g] + dd[g]*tb[g][:, None]
        nrm = p/np.linalg.norm(p, axis=1)[:, None]
        cosi = -np.einsum('ij,ij->i', dd[g], nrm)  # cos wrt outward normal of fixedDir (>0: entering)
        F, tir = fresnel(cosi, ior)
        entering = cosi > 0
        eta = np.where(entering, 1/ior, ior)
        trans = (1-F)*eta*eta; refl = F
        thr = np.where(tir, 0.0, np.where(refl > 0, np.clip(trans/(trans+refl), .25, .75), 1.0))
        ug = u[g] if correlated else rng.random(j.size)
        ug = np.where(ins[g], ug, rng.random(j.size))  # from outside there was no volume segment
        tr = ug < thr
        # directions
        sint2 = eta*eta*np.maximum(0, 1-cosi*cosi)
        cost = np.sqrt(np.maximum(0, 1-sint2))
        n_in = np.where(entering[:, None], nrm, -nrm)  # normal on the incident side
        tdir = eta[:, None]*dd[g] + (eta*np.abs(cosi) - cost)[:, None]*n_in
        rdir = dd[g] + 2*(np.abs(cosi))[:, None]*np.where(entering[:, None], nrm, -nrm)
        newd = np.where(tr[:, None], tdir, rdir); newd /= np.linalg.norm(newd, axis=1)[:, None]
        wf = np.where(tr, trans/np.where(thr > 0, thr, 1), refl/np.where(thr < 1, 1-thr, 1))
        w[j] *= wf
        o[j] = p; d[j] = newd
        inside[j] = np.where(tr, ~inside[j], inside[j])
        depth[j] += 1
        cap = depth >= K
        alive &= ~cap
    return val.mean(), val.std()/np.sqrt(n)
if __name__ == "__main__":
    for ior in (1.5, 1.01):
        for s in (0.25, 0.5, 1, 2, 4):
            a = run(s, ior, True); b = run(s, ior, False)
            print(f"ior {ior} sigma {s}: correlated u {a[0]:.4f} +- {a[1]:.4f}   independent u {b[0]:.4f} +- {b[1]:.4f}")
