#!/usr/bin/env python3
"""Mitsuba 3's GGX BSDFs evaluated at fixed directions: the independent reference of
tests/render/ggx.rs's `ggx_matches_mitsuba_pointwise` (tests/render/data/ggx_mitsuba.csv).

Mitsuba is a reference only, never a dependency: run this in the venv that
scripts/bench-vs-mitsuba.sh makes (target/mitsuba-venv, mitsuba 3.9.1 + drjit 1.5.0):
    target/mitsuba-venv/bin/python scripts/ggx_mitsuba_reference.py > tests/render/data/ggx_mitsuba.csv
Mitsuba's `eval(si.wi, wo)` is f_r·cosθ(wo) with si.wi toward the viewer: hilcam's
`eval_cos(wo, wi)` with hilcam's wo = Mitsuba's si.wi. scalar_rgb with grey parameters,
channel 0.
"""
import math

import mitsuba as mi

mi.set_variant("scalar_rgb")

# (case, Mitsuba BSDF dict); hilcam builds the same in the test, by case name.
CASES = [
    ("conductor_au_a0.09", {"type": "roughconductor", "distribution": "ggx", "alpha": 0.09,
                            "eta": 0.3804, "k": 2.4792}),
    ("conductor_al_a0.5", {"type": "roughconductor", "distribution": "ggx", "alpha": 0.5,
                           "eta": 1.2337, "k": 7.2602}),
    ("conductor_ag_a1", {"type": "roughconductor", "distribution": "ggx", "alpha": 1.0,
                         "eta": 0.1283, "k": 3.4801}),
    ("plastic_spec_a0.25", {"type": "roughplastic", "distribution": "ggx", "alpha": 0.25,
                            "int_ior": 1.5, "ext_ior": 1.0,
                            "diffuse_reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}}),
    ("plastic_rho0.5_a0.25", {"type": "roughplastic", "distribution": "ggx", "alpha": 0.25,
                              "int_ior": 1.5, "ext_ior": 1.0,
                              "diffuse_reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}}),
]


def direction(theta_deg, phi_deg):
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return [math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)]


def main():
    ctx = mi.BSDFContext()
    print("case,wo_x,wo_y,wo_z,wi_x,wi_y,wi_z,f_cos,pdf")
    for name, d in CASES:
        bsdf = mi.load_dict(d)
        for to in (0.0, 30.0, 60.0, 80.0):
            for ti in (5.0, 30.0, 55.0, 75.0, 85.0):
                for phi in (0.0, 90.0, 180.0):
                    wo = direction(to, 0.0)
                    wi = direction(ti, phi)
                    si = mi.SurfaceInteraction3f()
                    si.wi = mi.Vector3f(wo)
                    f = bsdf.eval(ctx, si, mi.Vector3f(wi))[0]
                    p = bsdf.pdf(ctx, si, mi.Vector3f(wi))
                    row = [name] + [f"{x:.9g}" for x in wo + wi] + [f"{f:.9g}", f"{p:.9g}"]
                    print(",".join(row))


if __name__ == "__main__":
    main()
