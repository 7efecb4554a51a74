# Skip model of LuxCore 2.11.2 PATHCPU in the half-space sphere (analog walk, optical units).
#  entry: camera ray crosses the null boundary at t_hit; continues from mint = t_hit + E(t_hit)
#         (scene.cpp pass-through)  -> skip a = sigma_t*E(t_hit) along the ray
#  scatter vertex p: NEE shadow ray from p itself (constantinfinitelight: Ray(orig,dir,0.f,...)),
#         MIS weight 0.5 (equal uniform pdfs, power heuristic);
#         continuation ray: eyeRay.Update(p, d) -> mint = E(p): skip b = sigma_t*E(p) along d.
#         If the skip passes the boundary, the hit is before mint and is missed: the path stays in
#         the "cloud" volume forever (lost).  Escape by continuation: MIS weight 0.5.
import numpy as np, sys
rng = np.random.default_rng(int(sys.argv[1]) if len(sys.argv)>1 and sys.argv[1].isdigit() else 1)
def E(v, emin=1e-5, emax=0.1):
    v = np.abs(np.asarray(v, np.float32))
    nxt = (v.view(np.uint32) + np.uint32(128)).view(np.float32)
    return np.clip(np.abs(nxt - v).astype(np.float64), emin, emax)
def region_samples(n, R=1.0, center=(0,0,0), cam=(0,0,-4), fov=30.0, W=16, H=16, region=(3,3,13,13)):
    cam=np.array(cam,float); c=np.array(center,float)
    x0,y0,x1,y1 = region
    px = rng.uniform(x0,x1,n); py = rng.uniform(y0,y1,n)
    t = np.tan(np.radians(fov)/2)
    u = (1-2*px/W)*t*W/H; v = (1-2*py/H)*t
    d = np.stack([u, v, np.ones(n)],1); d /= np.linalg.norm(d,axis=1)[:,None]
    oc = cam - c; b = d@oc; cc = oc@oc - R*R; disc = b*b-cc
    ok = disc>0; tt = -b - np.sqrt(np.maximum(disc,0))
    p = cam + tt[:,None]*d
    mu = -np.sum((p-c)/R*d,1)
    return ok, p, mu, tt
def walk(a, b, mu, c=0.5, wnee=0.5, K=64, lose=True):
    n = len(a); z = mu*(a + rng.exponential(size=n)); w = np.ones(n); res = np.zeros(n)
    alive = np.ones(n,bool)
    for k in range(K):
        w = w*c
        # NEE from the scatter point itself
        cz = rng.uniform(-1,1,n)
        tr = np.where(cz<0, np.exp(-z/np.maximum(-cz,1e-300)), 0.0)
        res += np.where(alive, w*wnee*tr, 0.0)
        # continuation with skip b along the new direction
        oz = rng.uniform(-1,1,n)
        s = z + b*oz
        lost = alive & (s < 0) & lose
        alive &= ~lost
        s = np.maximum(s, 0) if not lose else s
        zn = s + oz*rng.exponential(size=n)
        esc = alive & (zn < 0)
        res += np.where(esc, w*(1-wnee), 0.0)
        alive &= ~esc
        z = zn
        if not alive.any(): break
    return res
def predict(sigma_t, R=1.0, center=(0,0,0), cam=(0,0,-4), emin=1e-5, emax=0.1, n=1_000_000, entry=True, scat=True, wnee=0.5, lose=True):
    ok,p,mu,tt = region_samples(n,R,center,cam)
    a = sigma_t*E(tt, emin, emax) if entry else np.zeros(n)
    b = sigma_t*E(p, emin, emax).max(1) if scat else np.zeros(n)
    r = walk(a[ok], b[ok], mu[ok], wnee=wnee, lose=lose)
    return r.mean(), r.std()/np.sqrt(len(r)), np.median(a[ok]), np.median(b[ok])
if __name__ == "__main__":
    cases = [("no skip st=1e4", dict(sigma_t=1e4, entry=False, scat=False)),
             ("st=2e3", dict(sigma_t=2e3)),
             ("st=1e4", dict(sigma_t=1e4)),
             ("st=1e4 entry only", dict(sigma_t=1e4, scat=False)),
             ("st=1e4 scatter only", dict(sigma_t=1e4, entry=False)),
             ("st=1e5", dict(sigma_t=1e5)),
             ("st=2e3 emin1e-9", dict(sigma_t=2e3, emin=1e-9)),
             ("st=1e4 emin1e-9", dict(sigma_t=1e4, emin=1e-9)),
             ("x1000 st=10", dict(sigma_t=10, R=1000, cam=(0,0,-4000))),
             ("off100 st=1e4", dict(sigma_t=1e4, center=(100,0,0), cam=(100,0,-4))),
            ]
    for name, kw in cases:
        m,e,a,b = predict(**kw)
        print(f"{name:22s} {m:.5f} ± {e:.5f}   entry skip {a:.3f} mfp, scatter skip {b:.3f} mfp", flush=True)
