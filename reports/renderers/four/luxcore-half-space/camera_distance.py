# The half-space sphere (FINDINGS.md, "LuxCore half-space: the mechanism") rendered by LuxCore at a
# chosen camera distance and field of view, writing scratch files under ./out/.
# Run with the LuxCore venv's python (it runs the driver with the same interpreter).
# usage: camera_distance.py name sigma_t cx cy cz camdist fov [eps_min] [seeds] [spp]
import json, subprocess, sys, os, numpy as np, OpenEXR
name, st, cx, cy, cz, D, fov = sys.argv[1], float(sys.argv[2]), *map(float, sys.argv[3:8])
eps = sys.argv[8] if len(sys.argv) > 8 and sys.argv[8] != "-" else None
seeds = int(sys.argv[9]) if len(sys.argv) > 9 else 6
spp = int(sys.argv[10]) if len(sys.argv) > 10 else 256
R = float(os.environ.get("R", "1"))
os.makedirs(f"out/{name}", exist_ok=True)
sc = {"camera":{"fov_y_deg":fov,"look_at":[cx,cy,cz],"medium":None,"position":[cx,cy,cz-D],"up":[0.0,1.0,0.0]},
 "exported_by":"furnace 0.1.0","format":"furnace-scene-json",
 "lights":[{"radiance_rgb":[1.0,1.0,1.0],"type":"environment"}],"materials":[{"type":"null"}],
 "media":[{"phase":{"type":"isotropic"},"sigma_a_rgb":[st/2]*3,"sigma_s_rgb":[st/2]*3}],
 "render":{"height":16,"max_depth":None,"spp":spp,"width":16},
 "shapes":[{"center":[cx,cy,cz],"emission":None,"exterior":None,"flip_normals":False,"interior":0,"material":0,"radius":R,"type":"sphere"}],"version":1}
json.dump(sc, open(f"out/{name}/scene.json","w"))
vals = []
for s in range(seeds):
    cmd = [sys.executable, os.path.join(os.path.dirname(os.path.abspath(__file__)), "../../../../reference/luxcore/render.py"), "--scene", f"out/{name}/scene.json",
           "--out", f"out/{name}/b{s}.exr", "--spp", str(spp), "--seed", str(1000+s), "--width", "16", "--height", "16",
           "--max-depth", "-1", "--threads", "2"]
    if eps: cmd += ["--luxcore-epsilon-min", eps]
    cmd += os.environ.get("EXTRA", "").split()
    subprocess.run(cmd, check=True, capture_output=True)
    f = OpenEXR.File(f"out/{name}/b{s}.exr")
    ch = f.channels()
    img = np.mean([np.asarray(ch[c].pixels, float) for c in "RGB"], 0) if "R" in ch else np.asarray(ch["RGB"].pixels,float).mean(-1)
    vals.append(img[3:13, 3:13].mean())
vals = np.array(vals)
print(f"{name:14s} st={st:g} c=({cx:g},{cy:g},{cz:g}) D={D:g} fov={fov:g} eps={eps} R={R:g} {os.environ.get('EXTRA','')}: {vals.mean():.5f} ± {vals.std(ddof=1)/np.sqrt(len(vals)):.5f}  (n={len(vals)}x{spp}spp)", flush=True)
