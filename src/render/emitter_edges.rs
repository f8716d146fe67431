//! Emitter-edge supersampling: anti-aliasing of the outlines of directly visible emitters.
//!
//! A pixel that an emitter's outline crosses averages a very bright and a dark region; its value is the
//! emitter's radiance times the share of the pixel it covers, and the camera samples estimate that share. With
//! a Cornell box's ceiling light (radiance 20 against walls near 0.2), the few hundred such pixels held 26% of
//! a 64 spp render's squared error. Those pixels are found from the geometry before rendering: the outline
//! edges of the emissive triangles (edges that no second triangle of the same emission shares) are projected
//! into the image and the pixels they cross are marked ([`EmitterEdges::find`]). Triangles that face away from
//! the camera emit nothing toward it and are left out.
//!
//! In a marked pixel the light emitted by the first surface a camera ray hits, `Le(h(x))`, is estimated
//! apart from the rest of the path's light, `R(x)`: the path traced from the sample's pixel position `x`
//! estimates `R` alone ([`FirstEmission::Omit`](crate::integrator::FirstEmission)), and [`EDGE_RAYS`] more
//! camera rays through positions `x_k` estimate `Le` ([`PathTracer::first_surface_emission`]). The pixel
//! value is `E[Le(h(x))] + E[R(x)]`, each term's estimator is unbiased (every `x_k` is uniform over the
//! pixel), so their sum is. The `x_k` of sample `i` are the points `16i .. 16i + 15` of one Owen-scrambled
//! Sobol stream of the pixel ([`crate::math::sobol`]), so that the pixel's 16 × spp positions form one
//! stratified set: a straight edge's variance falls about as N^-1.5 in the number of positions.
//!
//! "Model no more than a scene needs": `auto` turns it on only where it is exact and cheap, and says why
//! not otherwise (`--explain`):
//! - no participating media (emission seen through a medium depends on where the path scatters first);
//! - no camera or triangle motion over the shutter;
//! - no thin lens (defocus spreads an outline over pixels its pinhole projection does not mark);
//! - at most [`MAX_EMISSIVE_TRIANGLES`] emissive triangles, and marked pixels at most
//!   [`MAX_MARKED_SHARE`] of the image, so the extra camera rays stay a small share of the render's rays.
//!
//! The marking depends on the frame's geometry only, never on samples: a render gives the same image for any
//! thread count, and crops and sample ranges merge bit for bit.
//!
//! [`PathTracer::first_surface_emission`]: crate::integrator::PathTracer::first_surface_emission

use crate::light::{AreaLight, Light};
use crate::math::{Vec2, Vec3};
use crate::scene::Scene;
use std::collections::HashMap;

/// Camera rays per sample that estimate the directly visible emission of a marked pixel.
pub const EDGE_RAYS: u32 = 16;
/// The largest share of the image's pixels that may be marked; more, and supersampling is off.
pub const MAX_MARKED_SHARE: f64 = 0.02;
/// The most emissive triangles whose outlines are traced; more, and supersampling is off.
pub const MAX_EMISSIVE_TRIANGLES: usize = 1 << 16;
/// Steps per pixel of length when walking a projected edge across the image.
const STEPS_PER_PIXEL: f32 = 4.0;
/// Camera-space depth at which edges are clipped in front of the camera.
const NEAR: f32 = 1e-4;

/// Whether to supersample the outlines of directly visible emitters. It is the `--emitter-edges` value, by its
/// [`Choice`](crate::params::Choice) name.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum EmitterEdgeSampling {
    /// Where the scene allows it exactly and cheaply (see the module documentation).
    #[default]
    Auto,
    /// Never: every pixel takes one camera ray per sample.
    Off,
}

impl crate::params::Choice for EmitterEdgeSampling {
    const CHOICES: &'static [(&'static str, Self)] = &[("auto", Self::Auto), ("off", Self::Off)];
}

/// The pixels of a frame that an emitter's outline crosses.
#[derive(Clone, Debug, PartialEq)]
pub struct EmitterEdges {
    width: usize,
    marked: Vec<bool>,
    count: usize,
}

/// Why emitter-edge supersampling is on or off for a render.
#[derive(Clone, Debug, PartialEq)]
pub enum EdgeDecision {
    /// On, for these pixels.
    On(EmitterEdges),
    /// Off, for this reason (in words, for `--explain`).
    Off(String),
}

impl EdgeDecision {
    /// The marked pixels when on.
    pub fn edges(&self) -> Option<&EmitterEdges> {
        match self {
            EdgeDecision::On(e) => Some(e),
            EdgeDecision::Off(_) => None,
        }
    }

    /// The decision in words, for `--explain`.
    pub fn explain(&self) -> String {
        match self {
            EdgeDecision::On(e) => format!(
                "on: emitter outlines cross {} pixel(s) ({:.2}% of the image); each of their samples \
                 estimates the directly visible emission from {EDGE_RAYS} camera rays",
                e.count,
                100.0 * e.count as f64 / e.marked.len().max(1) as f64
            ),
            EdgeDecision::Off(why) => format!("off: {why}"),
        }
    }
}

impl EmitterEdgeSampling {
    /// The decision for `scene` rendered at `width` × `height`, in words (`--explain`).
    pub fn explain(self, scene: &Scene, width: usize, height: usize) -> String {
        self.decide(scene, width, height).explain()
    }

    internal! {
        /// Decides for `scene` rendered at `width` × `height`.
        pub fn decide(self, scene: &Scene, width: usize, height: usize) -> EdgeDecision {
            if self == EmitterEdgeSampling::Off {
                return EdgeDecision::Off("--emitter-edges off".into());
            }
            if !scene.media.is_empty() {
                return EdgeDecision::Off(
                    "the scene has participating media (emission seen through them depends on the path)".into(),
                );
            }
            if scene.camera.motion.is_some() || scene.moving_triangle_count() > 0 {
                return EdgeDecision::Off("the camera or triangles move over the shutter".into());
            }
            if scene.camera.lens.is_some() {
                return EdgeDecision::Off(
                    "the camera has a thin lens: defocus spreads emitter outlines beyond the pixels their projection crosses"
                        .into(),
                );
            }
            if scene.names().has_mattes() {
                return EdgeDecision::Off(
                    "the scene has holdouts or shadow catchers, which camera rays see differently"
                        .into(),
                );
            }
            EmitterEdges::find(scene, width, height)
        }
    }
}

/// The outline edges of `triangles`, in their order: an edge shared by two triangles of the same emission lies
/// inside an emitter, not on its outline, and is left out.
fn outline_edges(triangles: &[&AreaLight]) -> Vec<(Vec3, Vec3)> {
    let mut uses: HashMap<EdgeKey, u32> = HashMap::new();
    for l in triangles {
        for (a, b) in triangle_edges(l) {
            *uses.entry(edge_key(a, b, l)).or_default() += 1;
        }
    }
    triangles
        .iter()
        .flat_map(|l| triangle_edges(l).map(|(a, b)| (a, b, edge_key(a, b, l))))
        .filter(|(_, _, key)| uses[key] == 1)
        .map(|(a, b, _)| (a, b))
        .collect()
}

/// The three edges of an emissive triangle.
fn triangle_edges(l: &AreaLight) -> [(Vec3, Vec3); 3] {
    let v = l.vertices;
    [(v[0], v[1]), (v[1], v[2]), (v[2], v[0])]
}

/// The key of edge `a`–`b` of `light`: its ends (in either order) and the light's emission, bit for bit.
fn edge_key(a: Vec3, b: Vec3, light: &AreaLight) -> EdgeKey {
    let (a, b) = (
        a.to_array().map(f32::to_bits),
        b.to_array().map(f32::to_bits),
    );
    let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
    EdgeKey {
        ends: [lo, hi],
        emission: light.emission.to_array().map(f32::to_bits),
        texture: light.emission_texture,
    }
}

impl EmitterEdges {
    /// Marks the pixels of a `width` × `height` frame that an outline edge of an emissive triangle crosses
    /// (occlusion is not considered), or says why supersampling is off.
    pub fn find(scene: &Scene, width: usize, height: usize) -> EdgeDecision {
        let eye = scene.camera.position();
        let area_lights = || {
            scene.lights().iter().filter_map(|l| match l {
                Light::Area(a) => Some(a),
                _ => None,
            })
        };
        if area_lights().next().is_none() {
            return EdgeDecision::Off("no emissive triangles".into());
        }
        // Emission is one-sided: a triangle the camera sees from behind shows none, and where it meets a
        // triangle seen from the front (an emissive mesh's silhouette) the edge is an outline.
        let triangles: Vec<_> = area_lights()
            .filter(|a| a.normal.dot(eye - a.vertices[0]) > 0.0)
            .collect();
        if triangles.is_empty() {
            return EdgeDecision::Off("every emissive triangle faces away from the camera".into());
        }
        if triangles.len() > MAX_EMISSIVE_TRIANGLES {
            return EdgeDecision::Off(format!(
                "{} emissive triangles, more than {MAX_EMISSIVE_TRIANGLES}",
                triangles.len()
            ));
        }
        let pixels = width * height;
        let limit = (MAX_MARKED_SHARE * pixels as f64) as usize;
        let mut edges = EmitterEdges {
            width,
            marked: vec![false; pixels],
            count: 0,
        };
        let camera = &scene.camera;
        let aspect = width as f32 / height as f32;
        let size = Vec2::new(width as f32, height as f32);
        for (a, b) in outline_edges(&triangles) {
            let Some((a, b)) = clip_in_front(camera.to_camera_space(a), camera.to_camera_space(b))
            else {
                continue;
            };
            let raster = |p| camera.film_position(p, aspect).map(|f| f * size);
            if let (Some(a), Some(b)) = (raster(a), raster(b)) {
                edges.mark_segment(a, b, size);
                if edges.count > limit {
                    return EdgeDecision::Off(format!(
                        "emitter outlines cross more than {:.0}% of the image",
                        100.0 * MAX_MARKED_SHARE
                    ));
                }
            }
        }
        if edges.count == 0 {
            return EdgeDecision::Off("no emitter outline crosses the image".into());
        }
        EdgeDecision::On(edges)
    }

    /// Whether pixel (x, y) is marked.
    pub fn is_marked(&self, x: usize, y: usize) -> bool {
        self.marked[y * self.width + x]
    }

    /// Number of marked pixels.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Marks the pixels the raster-space segment `a`–`b` passes through, walking it in steps of a quarter
    /// pixel after clipping it to the image (a pixel it only grazes at a corner may be missed: that costs
    /// variance there, never bias).
    fn mark_segment(&mut self, a: Vec2, b: Vec2, size: Vec2) {
        let Some((a, b)) = clip_to_box(a, b, size) else {
            return;
        };
        let steps = ((b - a).length() * STEPS_PER_PIXEL).ceil().min(1e7) as usize + 1;
        for i in 0..=steps {
            let p = a.lerp(b, i as f32 / steps as f32);
            let (x, y) = (p.x.floor(), p.y.floor());
            if x >= 0.0 && y >= 0.0 && x < size.x && y < size.y {
                let at = y as usize * self.width + x as usize;
                if !self.marked[at] {
                    self.marked[at] = true;
                    self.count += 1;
                }
            }
        }
    }
}

/// An edge of an emissive triangle: its two ends (bit patterns, ordered) and the emission on it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct EdgeKey {
    ends: [[u32; 3]; 2],
    emission: [u32; 3],
    texture: Option<u32>,
}

/// The part of the camera-space segment `a`–`b` in front of the plane `z = −NEAR`, if any.
fn clip_in_front(a: Vec3, b: Vec3) -> Option<(Vec3, Vec3)> {
    let (ina, inb) = (a.z <= -NEAR, b.z <= -NEAR);
    match (ina, inb) {
        (true, true) => Some((a, b)),
        (false, false) => None,
        _ => {
            let t = (-NEAR - a.z) / (b.z - a.z);
            let c = a.lerp(b, t);
            Some(if ina { (a, c) } else { (c, b) })
        }
    }
}

/// The part of the 2-D segment `a`–`b` inside the box \[−1, size + 1\] (Liang–Barsky), if any.
fn clip_to_box(a: Vec2, b: Vec2, size: Vec2) -> Option<(Vec2, Vec2)> {
    if !(a.is_finite() && b.is_finite()) {
        return None;
    }
    let d = b - a;
    let (lo, hi) = (Vec2::splat(-1.0), size + 1.0);
    let (mut t0, mut t1) = (0.0f32, 1.0f32);
    for axis in 0..2 {
        let (p, q_lo, q_hi) = (d[axis], a[axis] - lo[axis], hi[axis] - a[axis]);
        for (p, q) in [(-p, q_lo), (p, q_hi)] {
            if p == 0.0 {
                if q < 0.0 {
                    return None;
                }
            } else {
                let t = q / p;
                if p < 0.0 {
                    t0 = t0.max(t);
                } else {
                    t1 = t1.min(t);
                }
            }
        }
    }
    (t0 <= t1).then(|| (a + d * t0, a + d * t1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clipping_keeps_the_visible_part() {
        let size = Vec2::new(10.0, 10.0);
        let (a, b) = clip_to_box(Vec2::new(-50.0, 5.0), Vec2::new(50.0, 5.0), size).unwrap();
        assert!((a.x + 1.0).abs() < 1e-4 && (b.x - 11.0).abs() < 1e-4);
        assert!(clip_to_box(Vec2::new(-5.0, -5.0), Vec2::new(-5.0, 20.0), size).is_none());
        let (a, b) = clip_in_front(Vec3::new(0.0, 0.0, -1.0), Vec3::new(0.0, 0.0, 1.0)).unwrap();
        assert_eq!(a.z, -1.0);
        assert!((b.z + NEAR).abs() < 1e-7);
        assert!(clip_in_front(Vec3::Z, Vec3::ONE).is_none());
    }

    #[test]
    fn a_segment_marks_the_pixels_it_crosses() {
        let mut e = EmitterEdges {
            width: 8,
            marked: vec![false; 64],
            count: 0,
        };
        // A diagonal from (0.5, 0.5) to (7.5, 7.5) crosses the 8 diagonal pixels and grazes no other.
        e.mark_segment(Vec2::splat(0.5), Vec2::splat(7.5), Vec2::splat(8.0));
        assert!((0..8).all(|i| e.is_marked(i, i)));
        assert_eq!(e.count(), 8, "only the diagonal: {:?}", e.marked);
    }
}
