//! TEMPORARY stub until the bsdf branch lands (Lambert only).
use crate::math::{sampling, Rgb, Vec2, Vec3};
/// stub
pub struct BsdfSample {
    pub wi: Vec3,
    pub f: Rgb,
    pub pdf: f32,
    pub is_delta: bool,
}
/// stub
#[derive(Clone, Copy, Debug, Default)]
pub struct PbrParams {
    pub base_color: Rgb,
    pub metallic: f32,
    pub roughness: f32,
    pub ior: f32,
    pub specular_factor: f32,
    pub specular_color: Rgb,
    pub transmission: f32,
}
/// stub
pub enum Bsdf {
    Lambert(Rgb),
}
impl Bsdf {
    /// stub
    pub fn from_gltf(p: &PbrParams) -> Bsdf {
        Bsdf::Lambert(p.base_color)
    }
    /// stub
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        let Bsdf::Lambert(a) = self;
        if wo.z <= 0.0 || wi.z <= 0.0 {
            Rgb::ZERO
        } else {
            *a / std::f32::consts::PI
        }
    }
    /// stub
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 {
            0.0
        } else {
            sampling::cosine_hemisphere_pdf(wi.z)
        }
    }
    /// stub
    pub fn sample(&self, wo: Vec3, _u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        let wi = sampling::cosine_hemisphere(u);
        let pdf = self.pdf(wo, wi);
        (pdf > 0.0).then(|| BsdfSample {
            wi,
            f: self.eval(wo, wi),
            pdf,
            is_delta: false,
        })
    }
    /// stub
    pub fn is_delta(&self) -> bool {
        false
    }
    /// stub
    pub fn albedo(&self) -> Rgb {
        let Bsdf::Lambert(a) = self;
        *a
    }
    /// stub
    pub fn is_index_matched(&self) -> bool {
        false
    }
}
