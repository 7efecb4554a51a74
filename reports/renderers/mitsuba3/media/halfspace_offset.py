"""The half-space collapse (FINDINGS.md, "The half-space mechanism"): a sphere of homogeneous
isotropic medium (albedo 0.5) behind a null boundary under a constant environment of 1, seen
from outside; the centre region's R over `SEEDS` (env, default 2) renders of 16x16 px at 256 spp.
The semi-infinite medium's reflectance is 0.1276 (furnace's closed form). Cases by name: base1e4,
base1e5, base3e3, base1e3, base3e4 (sigma_t), x1000 (scene scaled 1000x, sigma_t 10), off100 (moved
100 units in x), shiftz+1, shiftz-1, shiftx0.5 (sphere and camera moved together: same optics,
other |p|). Usage: python halfspace_offset.py VARIANT CASE..."""
import sys, numpy as np, drjit as dr, mitsuba as mi
mi.set_variant(sys.argv[1] if len(sys.argv)>1 else 'llvm_ad_rgb')
dr.set_thread_count(2)
def render(sigma_t, R=1.0, center=(0,0,0), cam=(0,0,-4), spp=256, seeds=int(__import__("os").environ.get("SEEDS","2")), albedo=0.5):
    c = np.array(center,float); cam=np.array(cam,float)
    scene = mi.load_dict({'type':'scene',
      'integrator':{'type':'volpath','max_depth':-1},
      'sensor':{'type':'perspective','fov':30,'fov_axis':'y','near_clip':0.0005*R,'far_clip':5000*R,
        'to_world':mi.ScalarTransform4f().look_at(origin=cam.tolist(),target=c.tolist(),up=[0,1,0]),
        'sampler':{'type':'independent','sample_count':spp},
        'film':{'type':'hdrfilm','width':16,'height':16,'rfilter':{'type':'box'},'pixel_format':'rgb'}},
      'sphere':{'type':'sphere','center':c.tolist(),'radius':R,'bsdf':{'type':'null'},
        'interior':{'type':'homogeneous','sigma_t':float(sigma_t),'albedo':albedo,'phase':{'type':'isotropic'}}},
      'env':{'type':'constant','radiance':1.0}})
    vals=[]
    for s in range(seeds):
        img = np.array(mi.render(scene, seed=s, spp=spp))
        vals.append(img[3:13,3:13,0].mean())
    return np.mean(vals), np.std(vals)/np.sqrt(len(vals))
cases = {
 'base1e4':dict(sigma_t=1e4), 'base1e5':dict(sigma_t=1e5),
 'base3e3':dict(sigma_t=3e3), 'base1e3':dict(sigma_t=1e3), 'base3e4':dict(sigma_t=3e4),
 'x1000':dict(sigma_t=10,R=1000,cam=(0,0,-4000)),
 'off100':dict(sigma_t=1e4,center=(100,0,0),cam=(100,0,-4)),
 'shiftz+1':dict(sigma_t=1e4,center=(0,0,1),cam=(0,0,-3)),
 'shiftz-1':dict(sigma_t=1e4,center=(0,0,-1),cam=(0,0,-5)),
 'shiftx0.5':dict(sigma_t=1e4,center=(0.5,0,0),cam=(0.5,0,-4)),
}
for name in sys.argv[2:]:
    m,e = render(**cases[name])
    print(f"{name:10s} mitsuba {m:.5f} ± {e:.5f}", flush=True)
