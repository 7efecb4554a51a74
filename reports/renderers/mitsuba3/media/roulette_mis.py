"""volpathmis's roulette/MIS mismatch (FINDINGS.md, "The volpathmis mechanism"): a closed box
(cube, inward normals, diffuse R = 0.5, emission 0.5; exact reading 1 at unlimited depth), the
camera inside a homogeneous isotropic medium (or in vacuum with the last argument `vacuum`),
rendered by the given integrator with the given rr_depth and max_depth; prints the mean over
`seeds` renders of 16x16 px at `spp` with its standard error. Usage: python roulette_mis.py
VARIANT INTEGRATOR SIGMA_S SIGMA_A RR_DEPTH MAX_DEPTH SPP SEEDS [vacuum]"""
import sys, os, numpy as np
import mitsuba as mi
variant, integ, ss, sa, rr, md, spp, K = sys.argv[1:9]
extra = sys.argv[9:]
mi.set_variant(variant)
ss, sa, rr, md, spp, K = float(ss), float(sa), int(rr), int(md), int(spp), int(K)
R = float(os.environ.get("R", 0.5)); E = 1 - R
st = ss + sa
med = {'type': 'homogeneous', 'sigma_t': st, 'albedo': (ss / st if st > 0 else 0.0),
       'phase': {'type': 'isotropic'}}
sensor = {'type': 'perspective', 'fov': 100,
          'to_world': mi.ScalarTransform4f().look_at(origin=[-0.4, -0.2, -0.6], target=[1, 1, 1], up=[0, 1, 0]),
          'sampler': {'type': 'independent', 'sample_count': spp},
          'film': {'type': 'hdrfilm', 'width': 16, 'height': 16, 'rfilter': {'type': 'box'}, 'pixel_format': 'rgb'}}
if 'vacuum' not in extra:
    sensor['medium'] = med
scene = mi.load_dict({'type': 'scene',
    'integrator': {'type': integ, 'max_depth': md, 'rr_depth': rr},
    'sensor': sensor,
    'box': {'type': 'cube', 'flip_normals': True,
            'bsdf': {'type': 'twosided', 'b': {'type': 'diffuse', 'reflectance': R}},
            'emitter': {'type': 'area', 'radiance': E}}})
ms = []
for k in range(K):
    img = np.array(mi.render(scene, seed=k + 1, spp=spp))
    ms.append(img[..., :3].mean())
ms = np.array(ms)
print(f"{variant} {integ:10s} ss={ss} sa={sa} rr={rr} md={md} {' '.join(extra)}: {ms.mean():.5f} +- {ms.std(ddof=1)/np.sqrt(K):.5f}", flush=True)
