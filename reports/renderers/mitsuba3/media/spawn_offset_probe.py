"""How deep below a sphere's surface Mitsuba's si.spawn_ray puts a ray's origin (the offset
(1 + max|p|) * RayEpsilon along the normal), at radius 1, 1000 and 100 units off the origin.
Usage: python spawn_offset_probe.py VARIANT"""
import drjit as dr, mitsuba as mi, sys
mi.set_variant(sys.argv[1])
dr.set_thread_count(2) if hasattr(dr,'set_thread_count') else None
print("RayEpsilon", mi.math.RayEpsilon, "ShadowEpsilon", mi.math.ShadowEpsilon)
for R,c,cam in [(1,0,-4),(1000,0,-4000),(1,100,-4)]:
    scene = mi.load_dict({'type':'scene','s':{'type':'sphere','center':[c,0,0],'radius':R,'bsdf':{'type':'null'}}})
    ray = mi.Ray3f(mi.Point3f(c,0,cam*1.0), mi.Vector3f(0,0,1))
    si = scene.ray_intersect(ray)
    r2 = si.spawn_ray(ray.d)
    o = r2.o
    depth = R - dr.norm(o - mi.Point3f(c,0,0))
    print(f"R={R} center x={c}: hit p={si.p}, spawned origin depth below surface = {depth}")
