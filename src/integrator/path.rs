//! The path tracer: next-event estimation at every non-delta scattering event, BSDF sampling to continue the
//! path, and multiple importance sampling of both strategies with the power heuristic (Veach 1997, §9.2,
//! eq. 9.13). Russian roulette (Arvo & Kirk 1990) ends low-throughput paths after a few bounces.
//!
//! `max_depth` counts scattering events, as pbrt's `maxdepth`: 0 shows emitters seen directly, 1 adds direct
//! lighting, and so on. Crossing an index-matched boundary (transmission 1, ior 1, smooth) is not a scattering
//! event and does not count.

use super::services::{offset_origin, RendererServices};
use super::RayCounters;
use crate::math::{sampling::power_heuristic, Frame, Ray, Rgb, Rng, Vec3};

/// Bounces after which Russian roulette may end a path.
const ROULETTE_START: u32 = 3;
/// Invisible-boundary crossings allowed per path, a guard against degenerate geometry.
const MAX_BOUNDARY_CROSSINGS: u32 = 256;

/// What one camera path returns: its radiance and the first hit's AOVs.
#[derive(Clone, Copy, Debug, Default)]
pub struct PathSample {
    /// Radiance carried to the camera.
    pub radiance: Rgb,
    /// Albedo of the first visible surface (zero when the ray escapes).
    pub albedo: Rgb,
    /// World-space shading normal of the first visible surface, facing the camera.
    pub normal: Vec3,
    /// Distance from the camera to the first visible surface (0 when the ray escapes).
    pub depth: f32,
}

/// The path tracer and its settings.
#[derive(Clone, Copy, Debug)]
pub struct PathTracer {
    /// Maximum number of scattering events per path.
    pub max_depth: u32,
}

impl PathTracer {
    /// Traces one camera path.
    pub fn trace(
        &self,
        services: &RendererServices,
        mut ray: Ray,
        rng: &mut Rng,
        counters: &mut RayCounters,
    ) -> PathSample {
        let scene = services.scene();
        let mut out = PathSample::default();
        let mut radiance = Rgb::ZERO;
        let mut beta = Rgb::ONE;
        let mut depth = 0u32;
        let mut crossings = 0u32;
        // State of the previous scattering event, for MIS on emitters hit by BSDF sampling.
        let mut prev_delta = true;
        let mut prev_pdf = 0.0f32;
        let mut prev_p = ray.origin;
        let mut first_hit = true;
        counters.camera += 1;
        loop {
            let Some(hit) = scene.intersect(&ray, 0.0, f32::INFINITY) else {
                if let Some(env) = scene.environment_light() {
                    let le = env.radiance(ray.dir);
                    let weight = if prev_delta {
                        1.0
                    } else {
                        power_heuristic(prev_pdf, services.environment_pdf(ray.dir))
                    };
                    radiance += beta * le * weight;
                }
                break;
            };
            let material = &scene.materials[hit.material as usize];
            let wo_world = -ray.dir;
            if first_hit {
                first_hit = false;
                out.depth = (hit.p - ray.origin).length();
                out.albedo = material.pbr_params(hit.uv, &scene.textures).base_color;
                out.normal = if hit.shading.n.dot(wo_world) < 0.0 {
                    -hit.shading.n
                } else {
                    hit.shading.n
                };
            }
            // Light emitted by the surface toward the path.
            if hit.front_face && material.is_emissive() {
                let le = material.emission_at(hit.uv, &scene.textures);
                let weight = match scene.area_light_of(hit.prim) {
                    Some(light) if !prev_delta => {
                        power_heuristic(prev_pdf, services.area_light_pdf(light, prev_p, hit.p))
                    }
                    _ => 1.0,
                };
                radiance += beta * le * weight;
            }
            let bsdf = material.bsdf(hit.uv, &scene.textures);
            if bsdf.is_index_matched() {
                crossings += 1;
                if crossings > MAX_BOUNDARY_CROSSINGS {
                    break;
                }
                counters.bounce += 1;
                ray = Ray::new(offset_origin(hit.p, hit.geometric_normal, ray.dir), ray.dir);
                continue;
            }
            if depth >= self.max_depth {
                break;
            }
            // Orient the shading frame: one-sided surfaces reflect nothing from behind.
            let frame = if hit.front_face || material.is_transmissive() {
                hit.shading
            } else if material.double_sided {
                Frame {
                    s: hit.shading.s,
                    t: -hit.shading.t,
                    n: -hit.shading.n,
                }
            } else {
                break;
            };
            let wo = frame.to_local(wo_world);
            // Next-event estimation.
            if !bsdf.is_delta() {
                if let Some(chosen) = services.sample_light(hit.p, rng) {
                    let ls = chosen.sample;
                    let wi = frame.to_local(ls.wi);
                    let f = bsdf.eval(wo, wi) * wi.z.abs();
                    if f.max_element() > 0.0 {
                        let origin = offset_origin(hit.p, hit.geometric_normal, ls.wi);
                        let tr = services.transmittance(origin, ls.wi, ls.distance, counters);
                        if tr.max_element() > 0.0 {
                            let light_pdf = chosen.pmf * ls.pdf;
                            let weight = if ls.is_delta {
                                1.0
                            } else {
                                power_heuristic(light_pdf, bsdf.pdf(wo, wi))
                            };
                            radiance += beta * f * tr * ls.radiance * (weight / light_pdf);
                        }
                    }
                }
            }
            // Continue the path by sampling the BSDF.
            let Some(bs) = bsdf.sample(wo, rng.next_f32(), rng.next_2d()) else {
                break;
            };
            if bs.pdf.is_nan() || bs.pdf <= 0.0 || bs.f.max_element() <= 0.0 {
                break;
            }
            let wi_world = frame.to_world(bs.wi);
            beta *= bs.f * (bs.wi.z.abs() / bs.pdf);
            prev_delta = bs.is_delta;
            prev_pdf = bs.pdf;
            prev_p = hit.p;
            depth += 1;
            if depth > ROULETTE_START {
                let survive = beta.max_element().clamp(0.05, 1.0);
                if rng.next_f32() >= survive {
                    break;
                }
                beta /= survive;
            }
            counters.bounce += 1;
            ray = Ray::new(
                offset_origin(hit.p, hit.geometric_normal, wi_world),
                wi_world,
            );
        }
        out.radiance = radiance;
        out
    }
}
