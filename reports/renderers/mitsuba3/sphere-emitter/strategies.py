"""Finding 1 by estimator: the centre of a flip_normals sphere emitter (radiance 1, diffuse
reflectance 0.5), 8x8 px, direct light only; the exact reading is 1.5. `direct_em` and
`direct_bsdf` use one strategy each (Mitsuba's `direct` integrator), `direct_mis` both with MIS,
`path2` the path integrator at max_depth 2. Usage: python strategies.py VARIANT R INTEGRATOR SPP
[SHAPE [SEED]]; SHAPE sphere (default) or a PLY file (a mesh sphere, scaled by R)."""
import sys, time, numpy as np
import mitsuba as mi
variant, R, integ, spp = sys.argv[1], float(sys.argv[2]), sys.argv[3], int(sys.argv[4])
shape_kind = sys.argv[5] if len(sys.argv)>5 else 'sphere'
mi.set_variant(variant)
mi.set_log_level(mi.LogLevel.Error)
if integ=='path2': I={'type':'path','max_depth':2}
elif integ=='pathfull': I={'type':'path','max_depth':-1}
elif integ=='path1': I={'type':'path','max_depth':1}
elif integ=='direct_em': I={'type':'direct','emitter_samples':1,'bsdf_samples':0}
elif integ=='direct_bsdf': I={'type':'direct','emitter_samples':0,'bsdf_samples':1}
elif integ=='direct_mis': I={'type':'direct','emitter_samples':1,'bsdf_samples':1}
refl = {'type':'rgb','value':0.5} if 'rgb' in variant else 0.5
if shape_kind=='sphere':
    sh={'type':'sphere','radius':R,'flip_normals':True}
elif shape_kind=='sphere_out':  # no flip: normals outward, two-sided bsdf + emitter can't face in -> skip
    sh={'type':'sphere','radius':R,'flip_normals':False}
else:
    sh={'type':'ply','filename':shape_kind,'flip_normals':True,'to_world':mi.ScalarTransform4f().scale(R)}
sh.update({'bsdf':{'type':'diffuse','reflectance':refl},'emitter':{'type':'area','radiance':1.0}})
scene = mi.load_dict({'type':'scene','integrator':I,
  'sensor':{'type':'perspective','fov':60,'near_clip':float(__import__('os').environ.get('NEAR','0.01')),'to_world':mi.ScalarTransform4f().look_at(origin=[0,0,0],target=[0.3,0.2,1],up=[0,1,0]),
     'sampler':{'type':'independent','sample_count':spp},
     'film':{'type':'hdrfilm','width':8,'height':8,'rfilter':{'type':'box'},'pixel_format':'rgb'}},
  'sph':sh})
t=time.time()
img = np.array(mi.render(scene, spp=spp, seed=int(sys.argv[6]) if len(sys.argv)>6 else 0))
v = img[...,0].ravel()
print(f'{variant} R={R} {integ} {shape_kind} spp={spp}: mean {v.mean():.5f} +- {v.std()/np.sqrt(v.size):.5f} (pixel spread)  [{time.time()-t:.1f}s]')
