#!/usr/bin/env python3
"""Mitsuba 3 references for tests/suite/gltf_anisotropy.rs: the directional albedo E(wo) = ∫ f(wo, wi) cos θi dωi of an
anisotropic GGX metal of Fresnel 1, which is the image mean of an infinite plane of that metal under a constant
environment of radiance 1 seen by an orthographic camera (every pixel sees the same wo).

Mitsuba's `roughconductor` (`distribution = "ggx"`, `alpha_u` along the surface tangent dp/du, `alpha_v` across
it, the default `material = "none"`: eta 0, k 1, Fresnel 1, which is glTF's Schlick Fresnel for base colour 1)
uses the separable Smith G = G1(wo) G1(wi), while Nimbus uses the height-correlated G2 = 1 / (1 + Λ(wo) + Λ(wi)).
So the script gives, per case:
- `render`: Mitsuba's own render of the plane (`rectangle` turned about z by the anisotropy rotation, `constant`
  emitter, `orthographic` sensor, `path` with max_depth 2), separable G;
- `separable`: the same albedo by Monte Carlo over Mitsuba's `MicrofacetDistribution` (its visible-normal sampling
  and its `smith_g1`), weight F · G1(wo, m) G1(wi, m) / G1(wo, m), which must match `render` (it checks the
  procedure);
- `height-correlated`: the same estimator with weight G2 / G1(wo) = (1/G1(wo)) / (1/G1(wo) + 1/G1(wi) − 1), still
  Mitsuba's D, sampling and Λ (1/G1 = 1 + Λ): the reference for Nimbus, written into tests/suite/gltf_anisotropy.rs.
Directions are in the anisotropy frame (x = the direction of alpha_u): the view azimuth minus the rotation.

Run: DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 python3 tests/validation/anisotropy/mitsuba_reference.py
"""

import math

import drjit as dr
import mitsuba as mi
import numpy as np

mi.set_variant("llvm_ad_rgb")

SIZE = 16
PASSES = 16
PASS_SPP = 64
MC_SAMPLES = 4_000_000

# Roughness 0.3 and strength 0.9: alpha_t = mix(0.09, 1, 0.81) = 0.8271 along the anisotropy direction,
# alpha_b = 0.09 across it (KHR_materials_anisotropy).
ALPHA_T = 0.09 + 0.91 * 0.81
ALPHA_B = 0.09
# (name, alpha_u, alpha_v, rotation of the tangent about z (radians), view theta, view phi)
CASES = [
    ("view along the tangent", ALPHA_T, ALPHA_B, 0.0, 1.3, 0.0),
    ("view along the bitangent", ALPHA_T, ALPHA_B, 0.0, 1.3, math.pi / 2),
    ("rotation 0.5, view at azimuth 0.9", ALPHA_T, ALPHA_B, 0.5, 1.3, 0.9),
    ("head-on view", ALPHA_T, ALPHA_B, 0.0, 0.2, 0.0),
]


def scene(alpha_u, alpha_v, turn, theta, phi, seed):
    wo = [math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)]
    origin = [10.0 * c for c in wo]
    up = [0, 0, 1] if theta > 0.5 else [0, 1, 0]
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 2},
        "sensor": {
            "type": "orthographic",
            "to_world": mi.ScalarTransform4f().look_at(origin=origin, target=[0, 0, 0], up=up),
            "film": {"type": "hdrfilm", "width": SIZE, "height": SIZE, "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": PASS_SPP, "seed": seed},
        },
        "env": {"type": "constant", "radiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}},
        "plane": {
            "type": "rectangle",
            "to_world": mi.ScalarTransform4f().rotate([0, 0, 1], math.degrees(turn)).scale([50, 50, 1]),
            "bsdf": {"type": "roughconductor", "distribution": "ggx", "alpha_u": alpha_u, "alpha_v": alpha_v},
        },
    }


def render_mean(au, av, turn, theta, phi):
    means = []
    for p in range(PASSES):
        img = mi.render(mi.load_dict(scene(au, av, turn, theta, phi, 1000 + p)))
        means.append(float(np.array(img)[:, :, 0].mean()))
    mean = sum(means) / PASSES
    se = math.sqrt(sum((m - mean) ** 2 for m in means) / (PASSES - 1) / PASSES)
    return mean, se


def albedo(au, av, wo_local, seed):
    distr = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, au, av, True)
    rng = np.random.default_rng(seed)
    u = mi.Point2f(rng.random(MC_SAMPLES).astype(np.float32), rng.random(MC_SAMPLES).astype(np.float32))
    wo = mi.Vector3f(*[float(c) for c in wo_local])
    m, _ = distr.sample(wo, u)
    wi = mi.reflect(wo, m)
    g1o = distr.smith_g1(wo, m)
    g1i = distr.smith_g1(wi, m)
    up = wi.z > 0
    separable = dr.select(up, g1i, 0.0)
    correlated = dr.select(up & (g1i > 0), (1.0 / g1o) / (1.0 / g1o + 1.0 / g1i - 1.0), 0.0)
    out = []
    for w in (separable, correlated):
        a = np.array(w, dtype=np.float64)
        out.append((a.mean(), a.std() / math.sqrt(len(a))))
    return out


for k, (name, au, av, turn, theta, phi) in enumerate(CASES):
    a = phi - turn
    wo_local = [math.sin(theta) * math.cos(a), math.sin(theta) * math.sin(a), math.cos(theta)]
    r, r_se = render_mean(au, av, turn, theta, phi)
    (s, s_se), (c, c_se) = albedo(au, av, wo_local, 7 + k)
    print(f"{name} (alpha_u {au:.4f}, alpha_v {av:.4f}, rotation {turn}, theta {theta}, phi {phi:.6f}):")
    print(f"  render {r:.6f} ± {r_se:.6f} ({PASSES} x {PASS_SPP} spp, {SIZE}x{SIZE}); "
          f"separable {s:.6f} ± {s_se:.6f} (z {(r - s) / math.hypot(r_se, s_se):+.2f}); "
          f"height-correlated {c:.6f} ± {c_se:.6f} ({MC_SAMPLES} samples)")
