//! The spatial light sampler: a bounding volume hierarchy over the lights that have a position, traversed from
//! the root to one light with child probabilities proportional to an importance estimated at the shading point
//! (Conty Estevez & Kulla 2018, "Importance Sampling of Many Lights with Adaptive Tree Splitting", §4; PBRT4
//! §12.6.3, the BVH light sampler).
//!
//! - Bounded lights (emissive triangles, point and spot lights) are the leaves of a binary tree, one light per
//!   leaf. Every node bounds its lights by a box, a cone of emission directions (axis, θ_o the spread of the
//!   normals, θ_e the spread of emission about each normal) and their total power φ (the paper's §4.1). An
//!   emissive triangle's power includes its emissive texture's average over it
//!   ([`AreaLight::textured_power`](super::AreaLight::textured_power)): a mesh whose texture is dark over
//!   most of it spends its samples where it glows.
//! - The tree is built top-down with the paper's surface area orientation heuristic (§4.4): a split of a node
//!   into L and R costs K_r · Σ φ_c · M_A(c) · M_Ω(c), with M_A the box's surface area, M_Ω the orientation
//!   measure (the solid angle of the emission cone weighted by the cosine falloff beyond θ_o, PBRT4
//!   eq. 12.24) and K_r the ratio of the box's longest edge to its edge along the split axis.
//! - At a point p (with normal n at a surface), a node's importance is φ · cos θ' / d² (the paper's eq. 3):
//!   d² the squared distance to the box's centre, clamped below by the squared radius of the box's bounding
//!   sphere; θ' the angle between the cone and the direction to p, reduced by the cone's spread θ_o and by the
//!   angle θ_b the bounding sphere subtends at p, and zero beyond θ_e; at a surface the importance is also
//!   multiplied by the largest |cos| between n and a direction toward the box.
//! - Lights at infinity (directional, environment) are chosen first, together with the probability of their
//!   share of the total power (as the power sampler gives them), or all of it when no bounded light can light
//!   p; among themselves by power. (PBRT4 §12.6.3 gives each a fair share 1 / (n_infinite + 1) instead;
//!   measured on the DamagedHelmet benchmark under a dim sky, that took half the samples from the triangles
//!   and raised the MSE.)
//! - A light's probability for MIS is the product of the same child probabilities along its path from the root,
//!   which every leaf stores as a bit trail; it equals, bit for bit, the probability the sampler returned.

use super::Light;
use crate::material::Texture;
use crate::math::sampling::ONE_BELOW;
use crate::math::{luminance, Aabb, Distribution1D, Quat, Vec3};
use std::f32::consts::{FRAC_PI_2, PI};

/// Where a light is chosen for: the shading point, and at a surface its shading normal (whose cosine
/// bounds the light's contribution there). `n` is `None` inside media.
#[derive(Clone, Copy, Debug)]
pub struct LightContext {
    /// The shading point.
    pub p: Vec3,
    /// The unit shading normal at a surface; `None` at a scattering event in a medium.
    pub n: Option<Vec3>,
}

/// Bins per axis of the binned surface area orientation heuristic.
const BINS: usize = 12;
/// Deepest leaf allowed; a light's bit trail has one bit per level of a u64. The build switches to balanced
/// splits before a subtree could go deeper.
const MAX_DEPTH: usize = 61;

/// Spatial and directional bounds of a set of lights (the paper's §4.1).
#[derive(Clone, Copy, Debug)]
struct LightBounds {
    /// Box around the emitting points.
    bounds: Aabb,
    /// Axis of the cone of emitter normals.
    axis: Vec3,
    /// Spread θ_o of the normals about the axis, in [0, π].
    theta_o: f32,
    /// Spread θ_e of the emission about each normal, in [0, π/2] (π/2 for a cosine emitter).
    theta_e: f32,
    /// Total power, scaled so that φ · cos θ / d² is π times the irradiance a light gives at distance d.
    phi: f32,
}

impl LightBounds {
    /// The bounds of one light (an emissive triangle's power with its texture, `textures`); `None` for lights
    /// at infinity and lights that emit nothing.
    fn of(light: &Light, textures: &[Texture]) -> Option<LightBounds> {
        let bounds = match light {
            Light::Area(a) => LightBounds {
                bounds: a.vertices.iter().fold(Aabb::EMPTY, |b, &v| b.extend(v)),
                axis: a.normal,
                theta_o: 0.0,
                theta_e: FRAC_PI_2,
                phi: a.textured_power(textures),
            },
            Light::Point(l) => LightBounds {
                bounds: Aabb::new(l.position, l.position),
                axis: Vec3::Z,
                theta_o: PI,
                theta_e: FRAC_PI_2,
                phi: PI * luminance(l.intensity),
            },
            Light::Spot(l) => {
                let theta_o = l.cos_inner.clamp(-1.0, 1.0).acos();
                LightBounds {
                    bounds: Aabb::new(l.position, l.position),
                    axis: l.direction,
                    theta_o,
                    theta_e: (l.cos_outer.clamp(-1.0, 1.0).acos() - theta_o).max(0.0),
                    phi: PI * luminance(l.intensity),
                }
            }
            Light::Directional(_) | Light::Environment(_) => return None,
        };
        (bounds.phi > 0.0 && bounds.phi.is_finite()).then_some(bounds)
    }

    /// Bounds of the union of both sets: the boxes' union, the powers' sum and the smallest cone around both
    /// cones (the paper's Algorithm 1).
    fn union(&self, other: &LightBounds) -> LightBounds {
        let (wide, narrow) = if other.theta_o > self.theta_o {
            (other, self)
        } else {
            (self, other)
        };
        let theta_d = wide.axis.angle_between(narrow.axis);
        let (axis, theta_o) = if (theta_d + narrow.theta_o).min(PI) <= wide.theta_o {
            (wide.axis, wide.theta_o)
        } else {
            let theta_o = 0.5 * (wide.theta_o + theta_d + narrow.theta_o);
            let turn = wide.axis.cross(narrow.axis);
            if theta_o >= PI || turn.length_squared() < 1e-12 {
                (wide.axis, PI)
            } else {
                // Rotate the wide cone's axis toward the narrow one until both fit.
                let rotation = Quat::from_axis_angle(turn.normalize(), theta_o - wide.theta_o);
                ((rotation * wide.axis).normalize(), theta_o)
            }
        };
        LightBounds {
            bounds: self.bounds.union(&other.bounds),
            axis,
            theta_o,
            theta_e: self.theta_e.max(other.theta_e),
            phi: self.phi + other.phi,
        }
    }

    /// The orientation measure M_Ω: the integral over the sphere of the cosine falloff of the emission cone,
    /// 2π(1 − cos θ_o) + π/2 (2θ_w sin θ_o − cos(θ_o − 2θ_w) − 2θ_o sin θ_o + cos θ_o) with
    /// θ_w = min(θ_o + θ_e, π) (PBRT4 eq. 12.24, the integral of cos(θ − θ_o) over θ_o ≤ θ ≤ θ_w).
    fn orientation_measure(&self) -> f32 {
        let theta_w = (self.theta_o + self.theta_e).min(PI);
        let (sin_o, cos_o) = self.theta_o.sin_cos();
        2.0 * PI * (1.0 - cos_o)
            + FRAC_PI_2
                * (2.0 * theta_w * sin_o
                    - (self.theta_o - 2.0 * theta_w).cos()
                    - 2.0 * self.theta_o * sin_o
                    + cos_o)
    }

    /// The surface area orientation heuristic's cost of a child with these bounds (before K_r).
    fn cost(&self) -> f32 {
        self.phi * self.orientation_measure() * self.bounds.surface_area()
    }
}

/// A node of the light tree, in the form traversal reads: its bounds with the cone's cosines precomputed.
#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb,
    axis: Vec3,
    cos_o: f32,
    sin_o: f32,
    cos_e: f32,
    phi: f32,
    /// A leaf's light index, or an inner node's second child (its first child is the next node).
    content: Content,
}

#[derive(Clone, Copy, Debug)]
enum Content {
    Leaf(u32),
    Inner(u32),
}

/// How a light takes part in the sampler.
#[derive(Clone, Copy, Debug)]
enum Membership {
    /// A leaf of the tree, reached from the root by the bit trail (bit k set: the second child at depth k).
    Leaf(u64),
    /// One of the lights at infinity, chosen with a fair share.
    Infinite,
    /// Never chosen: it emits nothing.
    Dark,
}

/// cos and sin of max(0, θ_a − θ_b), from the cosines and sines of θ_a and θ_b in [0, π].
fn sub_clamped((cos_a, sin_a): (f32, f32), (cos_b, sin_b): (f32, f32)) -> (f32, f32) {
    if cos_a >= cos_b {
        (1.0, 0.0)
    } else {
        (cos_a * cos_b + sin_a * sin_b, sin_a * cos_b - cos_a * sin_b)
    }
}

/// `x` as a sampling weight: NaN and negative values are 0, infinity the largest finite value.
fn finite_weight(x: f32) -> f32 {
    if x > 0.0 {
        x.min(f32::MAX)
    } else {
        0.0
    }
}

/// sin θ from cos θ, for θ in [0, π].
fn sin_from_cos(cos: f32) -> f32 {
    (1.0 - cos * cos).max(0.0).sqrt()
}

impl Node {
    fn new(b: &LightBounds, content: Content) -> Node {
        let (sin_o, cos_o) = b.theta_o.sin_cos();
        Node {
            bounds: b.bounds,
            axis: b.axis,
            cos_o,
            sin_o: sin_o.max(0.0),
            cos_e: b.theta_e.cos(),
            phi: b.phi,
            content,
        }
    }

    /// The node's importance at `ctx` (the paper's eq. 3, with the cosine bound at surfaces; see the module
    /// documentation). Never NaN; at most `f32::MAX`.
    fn importance(&self, ctx: &LightContext) -> f32 {
        let center = self.bounds.center();
        let r2 = 0.25 * self.bounds.extent().length_squared();
        let to_p = ctx.p - center;
        let d2 = to_p.length_squared();
        let clamped_d2 = d2.max(r2).max(f32::MIN_POSITIVE);
        if d2 <= r2 {
            // Inside the bounding sphere: every direction may reach p.
            return finite_weight(self.phi / clamped_d2);
        }
        let w = to_p / d2.sqrt();
        let sin2_b = r2 / d2;
        let subtended = ((1.0 - sin2_b).sqrt(), sin2_b.sqrt());
        let cos_w = self.axis.dot(w);
        let outside_cone = sub_clamped((cos_w, sin_from_cos(cos_w)), (self.cos_o, self.sin_o));
        let (cos_prime, _) = sub_clamped(outside_cone, subtended);
        if cos_prime < self.cos_e {
            return 0.0;
        }
        let mut importance = self.phi * cos_prime / clamped_d2;
        if let Some(n) = ctx.n {
            let cos_i = n.dot(w).abs();
            importance *= sub_clamped((cos_i, sin_from_cos(cos_i)), subtended).0;
        }
        finite_weight(importance)
    }
}

/// The light BVH sampler (see the module documentation).
#[derive(Clone, Debug)]
pub struct LightBvh {
    nodes: Vec<Node>,
    /// How each light of the scene takes part, by light index.
    membership: Vec<Membership>,
    /// Indices of the lights at infinity that emit, and the distribution of their powers.
    infinite: Vec<u32>,
    infinite_powers: Option<Distribution1D>,
    /// Share of the lights at infinity in the total power, where a bounded light can light the point.
    infinite_share: f32,
}

impl LightBvh {
    /// Builds the tree over the bounded lights of `lights` (whose emissive textures are in `textures`);
    /// `scene_radius` sizes the lights at infinity as in [`Light::power`].
    pub fn new(lights: &[Light], textures: &[Texture], scene_radius: f32) -> LightBvh {
        Self::with_depth_cap(lights, textures, scene_radius, MAX_DEPTH)
    }

    /// Builds the tree with no leaf deeper than `depth_cap` (at most [`MAX_DEPTH`]).
    fn with_depth_cap(
        lights: &[Light],
        textures: &[Texture],
        scene_radius: f32,
        depth_cap: usize,
    ) -> LightBvh {
        let mut membership = vec![Membership::Dark; lights.len()];
        let (mut infinite, mut infinite_powers) = (Vec::new(), Vec::new());
        let mut items = Vec::new();
        for (i, light) in lights.iter().enumerate() {
            if let Some(b) = LightBounds::of(light, textures) {
                items.push((i as u32, b));
            } else if light.is_at_infinity() {
                let power = light.power(scene_radius);
                if power > 0.0 && power.is_finite() {
                    membership[i] = Membership::Infinite;
                    infinite.push(i as u32);
                    infinite_powers.push(power);
                }
            }
        }
        let infinite_total: f32 = infinite_powers.iter().sum();
        let mut bvh = LightBvh {
            nodes: Vec::with_capacity(2 * items.len()),
            membership,
            infinite,
            infinite_powers: (!infinite_powers.is_empty())
                .then(|| Distribution1D::new(&infinite_powers)),
            infinite_share: 0.0,
        };
        if !items.is_empty() {
            bvh.build(&mut items, 0, 0, depth_cap.min(MAX_DEPTH));
        }
        let bounded_total = bvh.nodes.first().map_or(0.0, |root| root.phi);
        bvh.infinite_share = infinite_total / (infinite_total + bounded_total);
        bvh
    }

    /// Builds the subtree over `items` at `depth`, reached by `trail`, with no leaf deeper than `depth_cap`;
    /// returns its root's index.
    fn build(
        &mut self,
        items: &mut [(u32, LightBounds)],
        depth: usize,
        trail: u64,
        depth_cap: usize,
    ) -> usize {
        let all = items
            .iter()
            .skip(1)
            .fold(items[0].1, |acc, (_, b)| acc.union(b));
        let index = self.nodes.len();
        if let [(light, _)] = items {
            self.nodes.push(Node::new(&all, Content::Leaf(*light)));
            self.membership[*light as usize] = Membership::Leaf(trail);
            return index;
        }
        self.nodes.push(Node::new(&all, Content::Inner(0)));
        // Balanced splits from here reach the cap at worst: ⌈log₂ n⌉ more levels.
        let balanced =
            depth + items.len().next_power_of_two().trailing_zeros() as usize >= depth_cap;
        let mid = match split_by_cost(items, &all.bounds) {
            Some(mid) if !balanced => mid,
            _ => split_in_half(items),
        };
        let (left, right) = items.split_at_mut(mid);
        self.build(left, depth + 1, trail, depth_cap);
        let second = self.build(right, depth + 1, trail | (1 << depth), depth_cap);
        self.nodes[index].content = Content::Inner(second as u32);
        index
    }

    /// Probability of choosing a light at infinity (all of them together) at `ctx`.
    fn infinite_probability(&self, ctx: &LightContext) -> f32 {
        if self.infinite.is_empty() {
            0.0
        } else if self
            .nodes
            .first()
            .is_none_or(|root| root.importance(ctx) <= 0.0)
        {
            1.0
        } else {
            self.infinite_share
        }
    }

    /// Probability of descending from the inner node `node` (second child `second`) into its first child:
    /// proportional to the children's importances, or to their powers where neither has any (so that every
    /// path through the tree keeps a probability and the probabilities of all lights sum to 1).
    fn first_child_probability(&self, node: usize, second: usize, ctx: &LightContext) -> f32 {
        let (a, b) = (&self.nodes[node + 1], &self.nodes[second]);
        let (ia, ib) = (a.importance(ctx), b.importance(ctx));
        let (wa, wb) = if ia > 0.0 || ib > 0.0 {
            (ia, ib)
        } else {
            (a.phi, b.phi)
        };
        // Scaled by the larger weight so the sum cannot overflow.
        let largest = wa.max(wb);
        let (wa, wb) = (wa / largest, wb / largest);
        wa / (wa + wb)
    }

    /// Chooses a light for `ctx` with `u` ∈ [0, 1): its index, the probability of choosing it and `u` rescaled
    /// to [0, 1) within the light's share of the unit interval (for stratified sampling of a point on it).
    /// `None` without lights.
    pub fn sample(&self, ctx: &LightContext, u: f32) -> Option<(usize, f32, f32)> {
        let p_infinite = self.infinite_probability(ctx);
        if u < p_infinite {
            let powers = self.infinite_powers.as_ref()?;
            let (k, p, rest) = powers.sample_discrete_remapped(u / p_infinite);
            return Some((self.infinite[k] as usize, p_infinite * p, rest));
        }
        if self.nodes.is_empty() {
            return None;
        }
        let mut u = ((u - p_infinite) / (1.0 - p_infinite)).min(ONE_BELOW);
        let mut pmf = 1.0 - p_infinite;
        let mut node = 0;
        loop {
            match self.nodes[node].content {
                Content::Leaf(light) => return Some((light as usize, pmf, u)),
                Content::Inner(second) => {
                    let second = second as usize;
                    let p_first = self.first_child_probability(node, second, ctx);
                    if u < p_first {
                        u = (u / p_first).min(ONE_BELOW);
                        pmf *= p_first;
                        node += 1;
                    } else {
                        u = ((u - p_first) / (1.0 - p_first)).min(ONE_BELOW);
                        pmf *= 1.0 - p_first;
                        node = second;
                    }
                }
            }
        }
    }

    /// Probability that [`Self::sample`] at `ctx` chooses light `index`: the same products, taken along the
    /// light's bit trail.
    pub fn pmf(&self, index: usize, ctx: &LightContext) -> f32 {
        let p_infinite = self.infinite_probability(ctx);
        let trail = match self.membership.get(index) {
            Some(Membership::Leaf(trail)) => *trail,
            Some(Membership::Infinite) => {
                let k = self.infinite.iter().position(|&l| l as usize == index);
                return match (k, &self.infinite_powers) {
                    (Some(k), Some(powers)) => p_infinite * powers.discrete_pdf(k),
                    _ => 0.0,
                };
            }
            _ => return 0.0,
        };
        let mut pmf = 1.0 - p_infinite;
        let (mut node, mut depth) = (0, 0);
        while let Content::Inner(second) = self.nodes[node].content {
            let second = second as usize;
            let p_first = self.first_child_probability(node, second, ctx);
            if trail >> depth & 1 == 0 {
                pmf *= p_first;
                node += 1;
            } else {
                pmf *= 1.0 - p_first;
                node = second;
            }
            depth += 1;
        }
        pmf
    }
}

/// The cheapest split of `items` (at least two) by the binned surface area orientation heuristic, over the
/// centroids in `BINS` bins per axis: reorders `items` so that the first part comes first and returns its
/// length; `None` when every centroid is the same.
fn split_by_cost(items: &mut [(u32, LightBounds)], node_box: &Aabb) -> Option<usize> {
    let centroids = items
        .iter()
        .fold(Aabb::EMPTY, |b, (_, l)| b.extend(l.bounds.center()));
    let extent = centroids.extent();
    let longest = node_box.extent().max_element();
    let bin_of = |b: &LightBounds, axis: usize| {
        let t = (b.bounds.center()[axis] - centroids.min[axis]) / extent[axis];
        ((t * BINS as f32) as usize).min(BINS - 1)
    };
    let mut best: Option<(f32, usize, usize)> = None;
    for axis in 0..3 {
        if extent[axis] <= 0.0 {
            continue;
        }
        let mut bins: [Option<LightBounds>; BINS] = [None; BINS];
        for (_, b) in items.iter() {
            let bin = &mut bins[bin_of(b, axis)];
            *bin = Some(bin.map_or(*b, |acc| acc.union(b)));
        }
        let union = |acc: Option<LightBounds>, b: &Option<LightBounds>| match (acc, b) {
            (Some(a), Some(b)) => Some(a.union(b)),
            (a, b) => a.or(*b),
        };
        let regularizer = longest / node_box.extent()[axis].max(f32::MIN_POSITIVE);
        for split in 1..BINS {
            let first = bins[..split].iter().fold(None, union);
            let second = bins[split..].iter().fold(None, union);
            if let (Some(first), Some(second)) = (first, second) {
                let cost = regularizer * (first.cost() + second.cost());
                if best.is_none_or(|(c, _, _)| cost < c) {
                    best = Some((cost, axis, split));
                }
            }
        }
    }
    let (_, axis, split) = best?;
    let mut mid = 0;
    for i in 0..items.len() {
        if bin_of(&items[i].1, axis) < split {
            items.swap(i, mid);
            mid += 1;
        }
    }
    Some(mid)
}

/// Splits `items` into two halves by count along the longest axis of their centroids; returns the first
/// half's length.
fn split_in_half(items: &mut [(u32, LightBounds)]) -> usize {
    let centroids = items
        .iter()
        .fold(Aabb::EMPTY, |b, (_, l)| b.extend(l.bounds.center()));
    let axis = centroids.extent().max_position();
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |a, b| {
        a.1.bounds.center()[axis].total_cmp(&b.1.bounds.center()[axis])
    });
    mid
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::{AreaLight, DirectionalLight, EnvironmentLight, PointLight, SpotLight};
    use crate::math::{sampling, Rgb, Rng, Vec2};

    /// A random scene of `n` bounded lights (mostly triangles facing every way, some point and spot lights),
    /// with a sun and a sky when `infinite`.
    fn random_lights(n: usize, infinite: bool, rng: &mut Rng) -> Vec<Light> {
        let mut lights = Vec::new();
        for i in 0..n {
            let c = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 8.0;
            let power = 0.1 + 3.0 * rng.next_f32();
            match i % 7 {
                5 => lights.push(Light::Point(PointLight {
                    position: c,
                    intensity: Rgb::splat(power),
                })),
                6 => lights.push(Light::Spot(SpotLight {
                    position: c,
                    direction: sampling::uniform_sphere(rng.next_2d()),
                    intensity: Rgb::splat(power),
                    cos_inner: 0.9,
                    cos_outer: 0.7,
                })),
                _ => {
                    let size = 0.05 + 0.5 * rng.next_f32();
                    let v = [0, 1, 2].map(|_| {
                        c + (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * size
                    });
                    if let Some(a) =
                        AreaLight::new(v, [Vec2::ZERO; 3], Rgb::splat(power), None, [0, 0])
                    {
                        lights.push(Light::Area(a));
                    }
                }
            }
        }
        if infinite {
            lights.push(Light::Directional(DirectionalLight {
                direction: -Vec3::Y,
                irradiance: Rgb::ONE,
            }));
            lights.push(Light::Environment(EnvironmentLight::Constant(Rgb::splat(
                0.2,
            ))));
        }
        lights
    }

    /// A random shading context: a point near the lights, with a random normal half of the time.
    fn random_context(rng: &mut Rng) -> LightContext {
        let p = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 12.0;
        let n = (rng.next_f32() < 0.5).then(|| sampling::uniform_sphere(rng.next_2d()));
        LightContext { p, n }
    }

    #[test]
    fn probabilities_sum_to_one_and_pmf_matches_sampling_exactly() {
        let mut rng = Rng::new(7, 1);
        for case in 0..60 {
            let n = [1, 2, 3, 5, 17, 64, 300][case % 7];
            let lights = random_lights(n, case % 2 == 0, &mut rng);
            let bvh = LightBvh::new(&lights, &[], 10.0);
            for _ in 0..20 {
                let ctx = random_context(&mut rng);
                let sum: f64 = (0..lights.len()).map(|i| bvh.pmf(i, &ctx) as f64).sum();
                assert!(
                    (sum - 1.0).abs() < 1e-4,
                    "case {case}: probabilities sum to {sum}"
                );
                for _ in 0..20 {
                    let u = rng.next_f32();
                    let (i, pmf, rest) = bvh.sample(&ctx, u).expect("lights to choose from");
                    assert!(
                        pmf > 0.0 && (0.0..1.0).contains(&rest),
                        "case {case}: {pmf} {rest}"
                    );
                    assert_eq!(pmf, bvh.pmf(i, &ctx), "case {case}: light {i} at {ctx:?}");
                }
            }
        }
    }

    #[test]
    fn a_light_facing_away_or_on_the_horizon_is_never_chosen() {
        // Two triangles: one faces the point, the other faces away; a point light in the surface's plane.
        let facing = AreaLight::new(
            [
                Vec3::new(-1.0, 2.0, -1.0),
                Vec3::new(1.0, 2.0, 0.0),
                Vec3::new(-1.0, 2.0, 1.0),
            ],
            [Vec2::ZERO; 3],
            Rgb::ONE,
            None,
            [0, 0],
        )
        .unwrap();
        assert!(facing.normal.y < 0.0);
        let mut away = facing.clone();
        away.vertices.swap(1, 2);
        away.normal = -away.normal;
        let level = Light::Point(PointLight {
            position: Vec3::new(3.0, 0.0, 0.0),
            intensity: Rgb::splat(100.0),
        });
        let lights = [Light::Area(facing), Light::Area(away), level];
        let bvh = LightBvh::new(&lights, &[], 10.0);
        let ctx = LightContext {
            p: Vec3::ZERO,
            n: Some(Vec3::Y),
        };
        assert_eq!(bvh.pmf(1, &ctx), 0.0, "faces away");
        assert_eq!(bvh.pmf(2, &ctx), 0.0, "on the horizon");
        assert_eq!(bvh.pmf(0, &ctx), 1.0);
    }

    #[test]
    fn chosen_lights_follow_their_pmf() {
        let mut rng = Rng::new(11, 2);
        let lights = random_lights(40, true, &mut rng);
        let bvh = LightBvh::new(&lights, &[], 10.0);
        for trial in 0..3 {
            let ctx = random_context(&mut rng);
            let mut draws = Rng::new(12, trial);
            crate::math::chi2::assert_discrete_sampler_fits(
                &format!("light bvh {trial}"),
                200_000,
                lights.len(),
                || bvh.sample(&ctx, draws.next_f32()).map(|(i, _, _)| i),
                |i| bvh.pmf(i, &ctx) as f64,
            );
        }
    }

    #[test]
    fn remapped_values_stay_uniform_within_the_chosen_light() {
        // For a fixed light, the rescaled values of the u that choose it are uniform on [0, 1).
        let mut rng = Rng::new(5, 3);
        let lights = random_lights(30, false, &mut rng);
        let bvh = LightBvh::new(&lights, &[], 10.0);
        let ctx = random_context(&mut rng);
        let (target, _, _) = bvh.sample(&ctx, 0.5).unwrap();
        let mut draws = Rng::new(6, 3);
        let rests: Vec<f32> = (0..400_000)
            .filter_map(|_| bvh.sample(&ctx, draws.next_f32()))
            .filter(|&(i, _, _)| i == target)
            .map(|(_, _, rest)| rest)
            .collect();
        assert!(rests.len() > 5000, "{} draws chose the light", rests.len());
        let mut k = 0;
        crate::math::chi2::assert_interval_sampler_fits(
            "remapped u",
            rests.len(),
            (0.0, 1.0),
            || {
                k += 1;
                rests[k - 1]
            },
            |_| 1.0,
        );
    }

    #[test]
    fn the_cone_union_holds_both_cones() {
        let mut rng = Rng::new(3, 4);
        for _ in 0..1000 {
            let cone = |rng: &mut Rng| LightBounds {
                bounds: Aabb::new(Vec3::ZERO, Vec3::ZERO),
                axis: sampling::uniform_sphere(rng.next_2d()),
                theta_o: rng.next_f32() * PI,
                theta_e: FRAC_PI_2,
                phi: 1.0,
            };
            let (a, b) = (cone(&mut rng), cone(&mut rng));
            let u = a.union(&b);
            for c in [a, b] {
                let reach = (u.axis.angle_between(c.axis) + c.theta_o).min(PI);
                assert!(reach <= u.theta_o + 1e-4, "{c:?} sticks out of {u:?}");
            }
        }
    }

    #[test]
    fn orientation_measure_of_a_cosine_emitter_and_of_a_point() {
        let one_sided = LightBounds {
            bounds: Aabb::EMPTY,
            axis: Vec3::Z,
            theta_o: 0.0,
            theta_e: FRAC_PI_2,
            phi: 1.0,
        };
        assert!((one_sided.orientation_measure() - PI).abs() < 1e-5);
        let everywhere = LightBounds {
            theta_o: PI,
            ..one_sided
        };
        assert!((everywhere.orientation_measure() - 4.0 * PI).abs() < 1e-5);
    }

    #[test]
    fn the_depth_cap_bounds_every_leaf_and_keeps_the_probabilities() {
        // Lights spaced geometrically along a line make the cost splits peel a few lights off the far end at a
        // time: an unbalanced tree, much deeper than log₂ n.
        let lights: Vec<Light> = (0..200)
            .map(|i| {
                Light::Point(PointLight {
                    position: Vec3::new(1.2f32.powi(i), 0.0, 0.0),
                    intensity: Rgb::splat(1.0),
                })
            })
            .collect();
        fn depth(nodes: &[Node], node: usize) -> usize {
            match nodes[node].content {
                Content::Leaf(_) => 0,
                Content::Inner(second) => {
                    1 + depth(nodes, node + 1).max(depth(nodes, second as usize))
                }
            }
        }
        let free = LightBvh::new(&lights, &[], 10.0);
        assert!(depth(&free.nodes, 0) > 12, "the cost splits alone go deep");
        let capped = LightBvh::with_depth_cap(&lights, &[], 10.0, 10);
        let deepest = depth(&capped.nodes, 0);
        assert!(
            (8..=10).contains(&deepest),
            "depth {deepest} under a cap of 10"
        );
        let mut rng = Rng::new(8, 8);
        for bvh in [&free, &capped] {
            for _ in 0..20 {
                let ctx = random_context(&mut rng);
                let sum: f64 = (0..lights.len()).map(|i| bvh.pmf(i, &ctx) as f64).sum();
                assert!((sum - 1.0).abs() < 1e-4, "{sum}");
                let (i, pmf, _) = bvh.sample(&ctx, rng.next_f32()).unwrap();
                assert_eq!(pmf, bvh.pmf(i, &ctx));
            }
        }
    }
}
