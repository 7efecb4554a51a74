"""Finding 1's mechanism, at the level of Mitsuba's sphere: for first hits of rays from the
centre on a flip_normals sphere (radius R), sample_direction and pdf_direction at the hit. Prints
the share of hits where the two pdfs disagree and how |p - c|/R is distributed (> 1 is where
pdf_direction takes the 'outside' cone branch). Usage: python pdf_mismatch.py VARIANT [R]
(the llvm variants need DRJIT_LIBLLVM_PATH)."""
import sys, numpy as np
import mitsuba as mi
variant = sys.argv[1]; R = float(sys.argv[2]) if len(sys.argv)>2 else 1.0
mi.set_variant(variant)
import drjit as dr
scene = mi.load_dict({'type':'scene',
  'sph':{'type':'sphere','radius':R,'flip_normals':True,
         'bsdf':{'type':'diffuse','reflectance':{'type':'rgb','value':0.5} if 'rgb' in variant else 0.5},
         'emitter':{'type':'area','radiance':1.0}}})
shape = scene.shapes()[0]; em = shape.emitter()
rng = np.random.default_rng(1)
N = 20000 if variant.startswith('llvm') else 3000
dirs = rng.normal(size=(N,3)); dirs /= np.linalg.norm(dirs,axis=1)[:,None]
n_cone = 0; ratios=[]; classes=[]
if variant.startswith('scalar'):
    for i in range(N):
        ray = mi.Ray3f(mi.Point3f(0,0,0), mi.Vector3f(*dirs[i]))
        si = scene.ray_intersect(ray)
        it = mi.Interaction3f(si)
        s = mi.Point2f(*rng.random(2))
        ds = shape.sample_direction(it, s)
        p_eval = shape.pdf_direction(it, ds)
        nrm = np.float32(dr.norm(si.p))
        classes.append(nrm)
        ratios.append(p_eval/ds.pdf if ds.pdf>0 else np.nan)
else:
    ray = mi.Ray3f(mi.Point3f(0,0,0), mi.Vector3f(dirs[:,0],dirs[:,1],dirs[:,2]))
    si = scene.ray_intersect(ray)
    it = mi.Interaction3f(si)
    s = mi.Point2f(rng.random(N), rng.random(N))
    ds = shape.sample_direction(it, s)
    p_eval = shape.pdf_direction(it, ds)
    classes = np.array(dr.norm(si.p))
    ratios = np.array(p_eval)/np.array(ds.pdf)
classes=np.array(classes,dtype=np.float32)/np.float32(R); ratios=np.array(ratios)
mism = np.abs(ratios-1)>1e-3
print(variant, 'R',R,'N',N,'mismatch frac %.4f'%mism.mean(), ' |p-c|/R: >1 %.3f, ==1 %.3f, <1 %.3f'%((classes>1).mean(),(classes==1).mean(),(classes<1).mean()))
print(' |p-c|/R -1 range', classes.min()-1, classes.max()-1)
print(' mean ratio pdf_direction/ds.pdf on mismatches', np.nanmean(ratios[mism]) if mism.any() else None)
