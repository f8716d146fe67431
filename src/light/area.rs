//! Area lights: every triangle whose material has a non-zero `emissiveFactor` (× `emissiveStrength`) emits
//! that radiance, optionally modulated by `emissiveTexture`, from its front (counter-clockwise) face only.
//! Sampled uniformly by area and converted to solid angle (PBRT4 §12.2).

use super::LightSample;
use crate::geometry::SurfacePoint;
use crate::material::{TexCoord, Texture};
use crate::math::{luminance, sampling, Rgb, Vec2, Vec3};

/// One emissive triangle.
#[derive(Clone, Debug)]
pub struct AreaLight {
    /// World-space vertices, counter-clockwise seen from the emitting side.
    pub vertices: [Vec3; 3],
    /// Texture coordinates at the vertices, of the set the emissive texture reads (zero without a texture);
    /// the texture's transform is applied at lookup.
    pub uvs: [Vec2; 3],
    /// Unit geometric normal of the emitting (front) side.
    pub normal: Vec3,
    /// Triangle area.
    pub area: f32,
    /// Emitted radiance when untextured; the texture, if any, multiplies it.
    pub emission: Rgb,
    /// Optional emissive texture index.
    pub emission_texture: Option<u32>,
    /// Global triangle index in the scene (its BVH primitive).
    pub prim: u32,
}

impl AreaLight {
    /// Builds the light for a triangle emitting `emission` (× `emission_texture` at `uvs`, if any); `None` for
    /// degenerate or non-emitting triangles.
    pub fn new(
        vertices: [Vec3; 3],
        uvs: [Vec2; 3],
        emission: Rgb,
        emission_texture: Option<u32>,
        prim: u32,
    ) -> Option<AreaLight> {
        let cross = (vertices[1] - vertices[0]).cross(vertices[2] - vertices[0]);
        let area = 0.5 * cross.length();
        let brightest = emission.max_element();
        if area.is_nan() || area <= 0.0 || brightest.is_nan() || brightest <= 0.0 {
            return None;
        }
        Some(AreaLight {
            vertices,
            uvs,
            normal: cross.normalize(),
            area,
            emission,
            emission_texture,
            prim,
        })
    }

    /// Emitted radiance leaving the light at barycentrics (b1, b2) in direction `w` (pointing away from it).
    pub fn radiance(&self, b1: f32, b2: f32, w: Vec3, textures: &[Texture]) -> Rgb {
        if self.normal.dot(w) <= 0.0 {
            return Rgb::ZERO;
        }
        match self.emission_texture.and_then(|t| textures.get(t as usize)) {
            Some(t) => {
                let uv = self.uvs[0] * (1.0 - b1 - b2) + self.uvs[1] * b1 + self.uvs[2] * b2;
                self.emission * t.lookup(t.map(TexCoord::point(uv))).truncate()
            }
            None => self.emission,
        }
    }

    /// Samples a point uniformly on the triangle and returns the incident radiance at `p` from it.
    pub fn sample_li(&self, p: Vec3, u: Vec2, textures: &[Texture]) -> Option<LightSample> {
        let (b0, b1) = sampling::uniform_triangle(u);
        let b2 = 1.0 - b0 - b1;
        let point = SurfacePoint::on_triangle(self.vertices, b0, b1, b2, self.normal);
        let q = point.p;
        let d = q - p;
        let dist2 = d.length_squared();
        if dist2.is_nan() || dist2 <= 0.0 {
            return None;
        }
        let distance = dist2.sqrt();
        let wi = d / distance;
        let radiance = self.radiance(b1, b2, -wi, textures);
        if radiance == Rgb::ZERO {
            return None;
        }
        let pdf = self.pdf_from_point(p, q)?;
        Some(LightSample {
            wi,
            radiance,
            pdf,
            point: Some(point),
            is_delta: false,
        })
    }

    /// Solid-angle density, seen from `p`, of sampling the point `q` on this light:
    /// `|p − q|² / (|cos θ_light| · area)`.
    pub fn pdf_from_point(&self, p: Vec3, q: Vec3) -> Option<f32> {
        let d = q - p;
        let dist2 = d.length_squared();
        let cos_light = self.normal.dot(d).abs() / dist2.sqrt();
        (cos_light > 1e-7).then(|| dist2 / (cos_light * self.area))
    }

    /// Emitted power π · L · area (luminance of the untextured emission).
    pub fn power(&self) -> f32 {
        std::f32::consts::PI * luminance(self.emission) * self.area
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_sided_emission_and_solid_angle_pdf() {
        let v = [
            Vec3::new(-1.0, 1.0, -1.0),
            Vec3::new(1.0, 1.0, -1.0),
            Vec3::new(-1.0, 1.0, 1.0),
        ];
        let l = AreaLight::new(v, [Vec2::ZERO; 3], Rgb::ONE, None, 0).unwrap();
        assert!(l.normal.distance(-Vec3::Y) < 1e-6, "normal {:?}", l.normal);
        assert!((l.area - 2.0).abs() < 1e-6);
        let s = l
            .sample_li(Vec3::ZERO, Vec2::new(0.3, 0.3), &[])
            .expect("lit from below");
        assert_eq!(s.radiance, Rgb::ONE);
        let distance = s.distance_from(Vec3::ZERO);
        let q = s.wi * distance;
        let cos = s.wi.y;
        assert!((s.pdf - distance * distance / (cos * 2.0)).abs() < 1e-4 * s.pdf);
        assert!(
            l.sample_li(Vec3::new(0.0, 2.0, 0.0), Vec2::new(0.3, 0.3), &[])
                .is_none(),
            "dark above"
        );
        assert!(l.pdf_from_point(Vec3::ZERO, q).is_some());
    }
}
