"""Is the committed Rayleigh-sky reference (rendered with volpathmis, rr_depth 5) touched by
volpathmis's roulette/MIS loss (FINDINGS.md)? Renders the reference's own export at 32x24 with
volpathmis at rr_depth 5 and with roulette off, same seeds, and prints the whole image's paired
relative difference per channel (and volpath's, which is NaN with chromatic media). Run from the
repository's root: python reports/renderers/mitsuba3/media/rayleigh_reference_roulette.py SPP SEEDS"""
import sys, numpy as np, mitsuba as mi
mi.set_variant('scalar_spectral'); mi.set_log_level(mi.LogLevel.Error)
scene=mi.load_file('reference/mitsuba/rayleigh-sky.export/scene.xml', width=32, height=24)
A=mi.load_dict({'type':'volpathmis','rr_depth':5,'max_depth':-1})
B=mi.load_dict({'type':'volpathmis','rr_depth':1000,'max_depth':1000})
C=mi.load_dict({'type':'volpath','rr_depth':5,'max_depth':-1})
spp,K=int(sys.argv[1]),int(sys.argv[2])
d=[];e=[];base=[]
for k in range(K):
    a=np.array(mi.render(scene,integrator=A,spp=spp,seed=k))[...,:3].reshape(-1,3).mean(0)
    b=np.array(mi.render(scene,integrator=B,spp=spp,seed=k))[...,:3].reshape(-1,3).mean(0)
    c=np.array(mi.render(scene,integrator=C,spp=spp,seed=k))[...,:3].reshape(-1,3).mean(0)
    d.append(a-b); e.append(c-b); base.append(b)
d=np.array(d); e=np.array(e); b=np.array(base).mean(0)
for name,x in (('volpathmis rr5 - roulette off',d),('volpath rr5 - volpathmis roulette off',e)):
    m=x.mean(0); s=x.std(0,ddof=1)/np.sqrt(K)
    print(name, ' '.join(f'{100*m[i]/b[i]:+.3f}% +- {100*s[i]/b[i]:.3f}%' for i in range(3)))
