//! Area lights: every triangle whose material has a non-zero `emissiveFactor` (× `emissiveStrength`) emits
//! that radiance, optionally modulated by `emissiveTexture`, from its front (counter-clockwise) face only.
//! Sampled uniformly by area and converted to solid angle (PBRT4 §12.2).

use super::LightSample;
use crate::geometry::SurfacePoint;
use crate::material::{TexCoord, Texture};
use crate::math::{luminance, sampling, Rgb, Vec2, Vec3};

/// The least share of its untextured power that [`AreaLight::textured_power`] gives a triangle.
pub const TEXTURED_POWER_FLOOR: f32 = 1e-3;

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
    /// Index of the scene mesh the triangle belongs to: the triangles of one mesh make one emitter when the
    /// light sampler is chosen ([`crate::light::LightSamplerChoice`]).
    pub mesh: u32,
}

impl AreaLight {
    /// Builds the light for triangle `prim` of mesh `mesh` emitting `emission` (× `emission_texture` at `uvs`,
    /// if any); `None` for degenerate or non-emitting triangles.
    pub fn new(
        vertices: [Vec3; 3],
        uvs: [Vec2; 3],
        emission: Rgb,
        emission_texture: Option<u32>,
        [prim, mesh]: [u32; 2],
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
            mesh,
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

    /// Emitted power with the emissive texture's average over the triangle: π · area · luminance(L · t̄),
    /// t̄ the mean of the texture at 7 points (centroid, vertices pulled a third of the way in, edge
    /// midpoints), each filtered over a footprint of a seventh of the triangle's area in texture space; at
    /// least [`TEXTURED_POWER_FLOOR`] of [`Self::power`], so that a triangle whose emission the points miss
    /// keeps a chance. Untextured: [`Self::power`]. The light BVH's φ (PBRT4 §12.6.3).
    pub fn textured_power(&self, textures: &[Texture]) -> f32 {
        let Some(t) = self.emission_texture.and_then(|t| textures.get(t as usize)) else {
            return self.power();
        };
        let [a, b, c] = self.uvs;
        let uv_area = 0.5 * (b - a).perp_dot(c - a).abs();
        // Barycentrics (b1, b2): the centroid, each vertex moved a third of the way to it, the edge midpoints.
        let (near, far) = (1.0 / 9.0, 7.0 / 9.0);
        let points = [
            (1.0 / 3.0, 1.0 / 3.0),
            (near, near),
            (far, near),
            (near, far),
            (0.5, 0.0),
            (0.5, 0.5),
            (0.0, 0.5),
        ];
        let footprint = (uv_area / points.len() as f32).sqrt();
        let mean = points
            .iter()
            .map(|&(b1, b2)| {
                let uv = a * (1.0 - b1 - b2) + b * b1 + c * b2;
                t.lookup(t.map(TexCoord { uv, footprint })).truncate()
            })
            .sum::<Rgb>()
            / points.len() as f32;
        let textured = std::f32::consts::PI * luminance(self.emission * mean) * self.area;
        textured.max(TEXTURED_POWER_FLOOR * self.power())
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
        let l = AreaLight::new(v, [Vec2::ZERO; 3], Rgb::ONE, None, [0, 0]).unwrap();
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

    #[test]
    fn textured_power_follows_the_texture_under_the_triangle() {
        use crate::material::{MipImage, Sampler};
        use crate::math::Vec4;
        use std::sync::Arc;
        // 64 × 64 texels: black on the left half (u < 0.5), white on the right.
        let texels = (0..64 * 64)
            .map(|i| {
                if i % 64 < 32 {
                    Vec4::new(0.0, 0.0, 0.0, 1.0)
                } else {
                    Vec4::ONE
                }
            })
            .collect();
        let image = Arc::new(MipImage::new(64, 64, texels).unwrap());
        let textures = [Texture::new(image, Sampler::default())];
        let v = [Vec3::ZERO, Vec3::X, Vec3::Z];
        let lit = |uvs| AreaLight::new(v, uvs, Rgb::splat(2.0), Some(0), [0, 0]).unwrap();
        let bright = lit([
            Vec2::new(0.6, 0.1),
            Vec2::new(0.9, 0.1),
            Vec2::new(0.6, 0.4),
        ]);
        let dark = lit([
            Vec2::new(0.05, 0.1),
            Vec2::new(0.3, 0.1),
            Vec2::new(0.05, 0.35),
        ]);
        let power = bright.power();
        let bright_power = bright.textured_power(&textures);
        assert!(
            (bright_power - power).abs() < 0.02 * power,
            "{bright_power} vs {power}"
        );
        let dark_power = dark.textured_power(&textures);
        assert!(
            dark_power >= TEXTURED_POWER_FLOOR * power && dark_power < 0.01 * power,
            "{dark_power} vs {power}"
        );
        let untextured = AreaLight::new(v, [Vec2::ZERO; 3], Rgb::splat(2.0), None, [0, 0]).unwrap();
        assert_eq!(untextured.textured_power(&textures), untextured.power());
    }
}
