"""f64 reference formulas (Walter et al. 2007 rough dielectric; GGX / Beckmann; exact dielectric Fresnel)
written from the papers, evaluated in numpy float64 at given (float32-representable) directions."""
import numpy as np
def D(m, a, kind):
    c2 = m[...,2]**2
    t = (m[...,0]**2 + m[...,1]**2)/(a*a)
    if kind == "ggx":
        return 1/(np.pi*a*a*(t + c2)**2)
    return np.exp(-t/c2)/(np.pi*a*a*c2*c2)
def G1(v, m, a, kind):
    xy = a*a*(v[...,0]**2+v[...,1]**2); t2 = xy/v[...,2]**2
    if kind == "ggx":
        r = 2/(1+np.sqrt(1+t2))
    else:
        aa = 1/np.sqrt(t2)
        r = np.where(aa >= 1.6, 1.0, (3.535*aa + 2.181*aa*aa)/(1 + 2.276*aa + 2.577*aa*aa))
    r = np.where(xy == 0, 1.0, r)
    return np.where((v*m).sum(-1)*v[...,2] <= 0, 0.0, r)
def fresnel(ci, eta):
    eta_it = np.where(ci >= 0, eta, 1/eta); eta_ti = 1/eta_it
    ct2 = 1 - (1 - ci*ci)*eta_ti**2
    ca = np.abs(ci); cta = np.sqrt(np.maximum(ct2, 0))
    a_s = (ca - eta_it*cta)/(ca + eta_it*cta); a_p = (cta - eta_it*ca)/(cta + eta_it*ca)
    return 0.5*(a_s**2 + a_p**2)
def rough_dielectric_fcos(wi, wo, a, eta, kind):
    """Mitsuba's eval (f times |cos of wo|) with si.wi = wi (viewer), wo = light, Radiance mode."""
    ci, co = wi[...,2], wo[...,2]
    refl = ci*co > 0
    e = np.where(ci > 0, eta, 1/eta); inv = 1/e
    m = wi + wo*np.where(refl, 1.0, e)[...,None]
    m = m/np.linalg.norm(m, axis=-1, keepdims=True)
    m = m*np.sign(m[...,2])[...,None]
    d = D(m, a, kind); F = fresnel((wi*m).sum(-1), eta); G = G1(wi,m,a,kind)*G1(wo,m,a,kind)
    r = F*d*G/(4*np.abs(ci))
    wim, wom = (wi*m).sum(-1), (wo*m).sum(-1)
    t = np.abs(inv**2*(1-F)*d*G*e*e*wim*wom/(ci*(wim + e*wom)**2))
    return np.where(refl, r, t)
def vndf_pdf(wi, wo, a, kind, eta=None):
    """pdf of Mitsuba-style visible-normal sampling (reflection for a conductor when eta is None,
    else rough dielectric with Fresnel lobe choice); wi = viewer (si.wi), wo = sampled."""
    ci, co = wi[...,2], wo[...,2]
    refl = ci*co > 0
    if eta is None:
        e = np.ones_like(ci)
    else:
        e = np.where(ci > 0, eta, 1/eta)
    m = wi + wo*np.where(refl, 1.0, e)[...,None]
    m = m/np.linalg.norm(m, axis=-1, keepdims=True)
    m = m*np.sign(m[...,2])[...,None]
    wim, wom = (wi*m).sum(-1), (wo*m).sum(-1)
    jac = np.where(refl, 1/(4*wom), e*e*wom/(wim + e*wom)**2)
    wis = wi*np.sign(ci)[...,None]
    p = D(m, a, kind)*G1(wis, m, a, kind)*np.abs((wis*m).sum(-1))/np.abs(ci)
    if eta is not None:
        F = fresnel(wim, eta)
        p = p*np.where(refl, F, 1-F)
    return p*np.abs(jac)


def hg(mu, g):
    """Henyey-Greenstein p(μ) per steradian, μ = cosine of the scattering angle (Henyey &
    Greenstein 1941), written with (1-g)² + 2g(1-μ) so that the peak does not cancel."""
    return (1 - g * g) / (4 * np.pi * ((1 - g) ** 2 + 2 * g * (1 - mu)) ** 1.5)


def hg_cdf(mu, g):
    """P(cos θ <= μ) for HG, closed form in f64 (the inverse of the textbook sampling formula)."""
    a = (1 - g) ** 2 + 2 * g * (1 - mu)
    return (1 - g * g) / (2 * g) * (1 / np.sqrt(a) - 1 / (1 + g))
