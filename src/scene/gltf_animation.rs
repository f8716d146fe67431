//! glTF animations sampled at one time: every channel of every animation drives its node's translation, rotation,
//! scale or morph weights (glTF 2.0 §3.11), with STEP, LINEAR (rotations by slerp) and CUBICSPLINE (the Hermite
//! spline of Appendix C) interpolation, held before the first key and after the last. The result is a pose:
//! each node's local matrix and morph weights at that time, which the loader uses in place of the file's.
//!
//! Accessors go through `gltf_accessors` (bounds, sparse data, normalized rotations and weights decoded);
//! key times must be finite and strictly increasing.
//!
//! Motion blur samples the animation across the shutter ([`shutter_poses`]): at motion steps evenly spaced
//! over it, `(frame + t) / fps` seconds for each step time `t`. There are [`MIN_STEPS`] steps, or more when a
//! node turns a lot: one step for every [`MAX_STEP_ANGLE_DEGREES`] of the largest rotation any node's world
//! matrix makes across the shutter (measured at [`PROBES`] instants), at most [`MAX_STEPS`]. Vertices are
//! interpolated linearly between steps, so a rotation's arc is cut to chords no longer than that angle
//! (a radius shrinks by at most 1 − cos 5° ≈ 0.4 % between steps).

use super::gltf_accessors::{read_floats, Usage};
use crate::frames::Shutter;
use crate::geometry::MotionSteps;
use crate::limits::Limits;
use crate::math::{Mat4, Quat, Vec3};
use gltf::animation::{Interpolation, Property};

/// Every node's local matrix and morph weights at one time.
pub(super) struct Pose {
    /// Local matrices, by node index.
    pub locals: Vec<Mat4>,
    /// Animated morph weights, by node index (`None`: the node's or mesh's own).
    pub weights: Vec<Option<Vec<f32>>>,
}

/// The pose of every node at `seconds`: the file's TRS where no channel targets a node, the channels' values
/// where one does (a later channel on the same property wins).
pub(super) fn pose_at(
    document: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    limits: &Limits,
    seconds: f32,
) -> Result<Pose, String> {
    let mut trs: Vec<(Vec3, Quat, Vec3)> = document
        .nodes()
        .map(|n| {
            let (t, r, s) = n.transform().decomposed();
            (Vec3::from(t), Quat::from_array(r), Vec3::from(s))
        })
        .collect();
    let mut animated = vec![false; trs.len()];
    let mut weights = vec![None; trs.len()];
    for (a, animation) in document.animations().enumerate() {
        for (c, channel) in animation.channels().enumerate() {
            let at = format!("animations[{a}].channels[{c}]");
            let sampler = channel.sampler();
            let times = read_floats(&sampler.input(), Usage::KeyTimes, buffers, limits)
                .map_err(|e| format!("{at} input: {e}"))?;
            if times.is_empty() {
                return Err(format!("{at}: the sampler has no keys"));
            }
            if !times.iter().all(|t| t.is_finite()) || times.windows(2).any(|w| w[0] >= w[1]) {
                return Err(format!(
                    "{at}: key times must be finite and strictly increasing"
                ));
            }
            let property = channel.target().property();
            let usage = match property {
                Property::Translation | Property::Scale => Usage::KeyVec3,
                Property::Rotation => Usage::KeyRotation,
                Property::MorphTargetWeights => Usage::KeyWeights,
            };
            let values = read_floats(&sampler.output(), usage, buffers, limits)
                .map_err(|e| format!("{at} output: {e}"))?;
            let interpolation = sampler.interpolation();
            let per_key = if interpolation == Interpolation::CubicSpline {
                3
            } else {
                1
            };
            let elements = values.len() / (times.len() * per_key).max(1);
            if elements == 0 || values.len() != elements * times.len() * per_key {
                return Err(format!(
                    "{at}: {} output values do not fit {} keys",
                    values.len(),
                    times.len()
                ));
            }
            let value = sample(&times, &values, elements, interpolation, seconds);
            let node = channel.target().node().index();
            let (t, r, s) = &mut trs[node];
            match property {
                Property::Translation => *t = Vec3::from_slice(&value),
                Property::Scale => *s = Vec3::from_slice(&value),
                Property::Rotation => {
                    *r = Quat::from_slice(&value).normalize();
                }
                Property::MorphTargetWeights => weights[node] = Some(value),
            }
            animated[node] |= property != Property::MorphTargetWeights;
        }
    }
    let locals = document
        .nodes()
        .zip(trs)
        .zip(&animated)
        .map(|((node, (t, r, s)), &moved)| {
            if moved {
                Mat4::from_scale_rotation_translation(s, r, t)
            } else {
                Mat4::from_cols_array_2d(&node.transform().matrix())
            }
        })
        .collect();
    Ok(Pose { locals, weights })
}

/// Motion steps across a shutter: there are at least this many.
pub(super) const MIN_STEPS: u32 = 3;
/// Motion steps across a shutter: at most this many.
pub(super) const MAX_STEPS: u32 = 32;
/// The largest rotation of a node between two motion steps, when [`MAX_STEPS`] allows.
pub(super) const MAX_STEP_ANGLE_DEGREES: f32 = 10.0;
/// The instants over the shutter at which node rotations are measured to choose the number of steps.
pub(super) const PROBES: usize = 9;

/// The animation sampled at motion steps across the shutter: each step's pose and node world matrices.
pub(super) struct ShutterPoses {
    /// When the steps are (frames relative to the frame).
    pub steps: MotionSteps,
    /// The pose at each step.
    pub poses: Vec<Pose>,
    /// Every node's world matrix at each step (see `gltf_deform::node_worlds`).
    pub worlds: Vec<Vec<Mat4>>,
}

/// Samples the animation at the motion steps of `shutter` around `frame` (see the module documentation for
/// how many); `None` for a shutter that is an instant (or not finite).
pub(super) fn shutter_poses(
    document: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    limits: &Limits,
    frame: i64,
    fps: f64,
    shutter: Shutter,
) -> Result<Option<ShutterPoses>, String> {
    let finite = shutter.open.is_finite() && shutter.close.is_finite();
    if !finite || shutter.open >= shutter.close {
        return Ok(None);
    }
    let sample = |times: Vec<f32>| -> Result<(Vec<Pose>, Vec<Vec<Mat4>>), String> {
        let poses = times
            .iter()
            .map(|&t| {
                let seconds = (frame as f64 + t as f64) / fps;
                pose_at(document, buffers, limits, seconds as f32)
            })
            .collect::<Result<Vec<_>, _>>()?;
        let worlds = poses
            .iter()
            .map(|p| super::gltf_deform::node_worlds(document, &p.locals))
            .collect();
        Ok((poses, worlds))
    };
    let (_, probes) = sample(shutter.sample_times(PROBES))?;
    let rotation = |m: &Mat4| Quat::from_mat4(&super::Camera::rigid(m)).normalize();
    let turn = (0..document.nodes().len())
        .map(|n| {
            probes
                .windows(2)
                .map(|w| rotation(&w[0][n]).angle_between(rotation(&w[1][n])))
                .filter(|a| a.is_finite())
                .sum::<f32>()
        })
        .fold(0.0f32, f32::max);
    let count = ((turn.to_degrees() / MAX_STEP_ANGLE_DEGREES).ceil() as u32 + 1)
        .clamp(MIN_STEPS, MAX_STEPS);
    let (poses, worlds) = sample(shutter.sample_times(count as usize))?;
    Ok(Some(ShutterPoses {
        steps: MotionSteps {
            open: shutter.open,
            close: shutter.close,
            count,
        },
        poses,
        worlds,
    }))
}

/// The value of a sampler with `elements` floats per key at `t` (glTF 2.0 Appendix C). `values` holds one
/// element per key, or for CUBICSPLINE three (in-tangent, value, out-tangent).
fn sample(
    times: &[f32],
    values: &[f32],
    elements: usize,
    interpolation: Interpolation,
    t: f32,
) -> Vec<f32> {
    let cubic = interpolation == Interpolation::CubicSpline;
    // The value (not a tangent) of key k.
    let key = |k: usize| -> &[f32] {
        let at = if cubic {
            (3 * k + 1) * elements
        } else {
            k * elements
        };
        &values[at..at + elements]
    };
    let last = times.len() - 1;
    if t <= times[0] {
        return key(0).to_vec();
    }
    if t >= times[last] {
        return key(last).to_vec();
    }
    let k = times.partition_point(|&key_time| key_time <= t) - 1;
    let dt = times[k + 1] - times[k];
    let s = (t - times[k]) / dt;
    match interpolation {
        Interpolation::Step => key(k).to_vec(),
        Interpolation::Linear if elements == 4 => {
            // Rotations: spherical linear interpolation (Appendix C, "slerp").
            let (a, b) = (Quat::from_slice(key(k)), Quat::from_slice(key(k + 1)));
            a.slerp(b, s).to_array().to_vec()
        }
        Interpolation::Linear => key(k)
            .iter()
            .zip(key(k + 1))
            .map(|(a, b)| a + s * (b - a))
            .collect(),
        Interpolation::CubicSpline => {
            let out_tangent = &values[(3 * k + 2) * elements..(3 * k + 3) * elements];
            let in_tangent = &values[3 * (k + 1) * elements..(3 * (k + 1) + 1) * elements];
            let (s2, s3) = (s * s, s * s * s);
            let (h00, h10, h01, h11) = (
                2.0 * s3 - 3.0 * s2 + 1.0,
                s3 - 2.0 * s2 + s,
                -2.0 * s3 + 3.0 * s2,
                s3 - s2,
            );
            (0..elements)
                .map(|i| {
                    h00 * key(k)[i]
                        + h10 * dt * out_tangent[i]
                        + h01 * key(k + 1)[i]
                        + h11 * dt * in_tangent[i]
                })
                .collect()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_linear_and_hold() {
        let times = [0.0, 1.0, 3.0];
        let values = [0.0, 10.0, 30.0];
        let at = |i, t| sample(&times, &values, 1, i, t)[0];
        assert_eq!(at(Interpolation::Linear, 0.5), 5.0);
        assert_eq!(at(Interpolation::Linear, 2.0), 20.0);
        assert_eq!(at(Interpolation::Step, 2.9), 10.0);
        assert_eq!(
            at(Interpolation::Linear, -1.0),
            0.0,
            "held before the first key"
        );
        assert_eq!(
            at(Interpolation::Linear, 9.0),
            30.0,
            "held after the last key"
        );
    }

    #[test]
    fn rotations_slerp() {
        let a = Quat::IDENTITY;
        let b = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
        let values: Vec<f32> = [a, b].iter().flat_map(|q| q.to_array()).collect();
        let q = Quat::from_slice(&sample(&[0.0, 1.0], &values, 4, Interpolation::Linear, 0.5));
        let want = Quat::from_rotation_y(std::f32::consts::FRAC_PI_4);
        assert!(q.angle_between(want) < 1e-5, "{q} vs {want}");
    }

    #[test]
    fn cubic_spline_is_the_hermite_curve() {
        // Keys 0 → 1 over 2 s with out-tangent 0.5 and in-tangent 0.5 (per second): the cubic with p(0) = 0,
        // p(2) = 1, p'(0) = p'(2) = 0.5 is the line p(t) = t/2; with zero tangents it is the smoothstep.
        let values = [0.0, 0.0, 0.5, 0.5, 1.0, 0.0];
        let p = sample(&[0.0, 2.0], &values, 1, Interpolation::CubicSpline, 0.5)[0];
        assert!((p - 0.25).abs() < 1e-6, "{p}");
        let flat = [0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let p = sample(&[0.0, 2.0], &flat, 1, Interpolation::CubicSpline, 0.5)[0];
        let s: f32 = 0.25;
        assert!((p - (3.0 * s * s - 2.0 * s * s * s)).abs() < 1e-6, "{p}");
    }
}
