"""Mitsuba-only isolation of the lossless-medium furnace bias (no furnace code runs here).

Renders each given Mitsuba scene (a `furnace export --format mitsuba3` of a lossless furnace
filled with a purely scattering medium) with both of Mitsuba's volumetric path tracers,
`volpath` and `volpathmis`, changing nothing else in the XML, and prints the image's mean
luminance over K independent seeds with its standard error and its deviation from EXPECTED
(times 1.001, Mitsuba's Y normalisation 1/106.750 against the CIE table's 1/106.857).

    python enclosure_integrators.py EXPECTED scene.xml [scene.xml ...]

The variant is llvm_ad_spectral unless MITSUBA_VARIANT names another (e.g. scalar_spectral).

Run from the folder holding each scene.xml's meshes (the XML names them relatively).
"""
import os
import sys

import mitsuba as mi
import numpy as np

mi.set_variant(os.environ.get("MITSUBA_VARIANT", "llvm_ad_spectral"))
K, SPP, SIZE = 16, 256, 16


def mean_y(xml, integrator):
    text = open(xml).read()
    for kind in ("volpathmis", "volpath"):
        text = text.replace(f'<integrator type="{kind}">', f'<integrator type="{integrator}">')
    for key, value in (("$spp", SPP), ("$width", SIZE), ("$height", SIZE), ("$seed", 0),
                       ("$max_depth", -1)):
        text = text.replace(key, str(value))
    here = os.getcwd()
    os.chdir(os.path.dirname(os.path.abspath(xml)))
    try:
        scene = mi.load_string(text)
    finally:
        os.chdir(here)
    means = []
    for k in range(K):
        rgb = np.array(mi.render(scene, seed=k + 1, spp=SPP))[..., :3]
        means.append((0.212671 * rgb[..., 0] + 0.715160 * rgb[..., 1] + 0.072169 * rgb[..., 2]).mean())
    return np.mean(means), np.std(means, ddof=1) / np.sqrt(K)


expected = float(sys.argv[1]) * 1.001
for xml in sys.argv[2:]:
    for integrator in ("volpath", "volpathmis"):
        m, se = mean_y(xml, integrator)
        print(f"{xml}  {integrator:10s}  Y = {m:.5f} +- {se:.5f}  "
              f"{(m / expected - 1) * 100:+.2f} %  z = {(m - expected) / se:+.1f}")
