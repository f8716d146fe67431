//! glTF animations sampled at one time: every channel of every animation drives its node's translation, rotation,
//! scale or morph weights (glTF 2.0 §3.11), with STEP, LINEAR (rotations by slerp) and CUBICSPLINE (the Hermite
//! spline of Appendix C) interpolation, held before the first key and after the last. The result is a pose:
//! each node's local matrix and morph weights at that time, which the loader uses in place of the file's.
//!
//! Accessors go through `accessors` (bounds, sparse data, normalized rotations and weights decoded);
//! key times must be finite and strictly increasing, and each output must hold one value per key (three for
//! CUBICSPLINE) of its property's size (3, 4, or the mesh's morph targets). Every sampler is read once per load
//! ([`Animations::read`]; an accessor shared by samplers once), within the memory budget, so that a pose costs
//! a binary search per channel however many poses a shutter samples.
//!
//! Motion blur samples the animation across the shutter ([`shutter_poses`]): at motion steps evenly spaced
//! over it, `(frame + t) / fps` seconds for each step time `t`. There are [`MIN_STEPS`] steps, or more when a
//! node turns a lot: one step for every [`MAX_STEP_ANGLE_DEGREES`] of the largest rotation any node's world
//! matrix makes across the shutter (measured at [`PROBES`] instants), at most [`MAX_STEPS`]. Vertices are
//! interpolated linearly between steps, so a rotation's arc is cut to chords no longer than that angle
//! (a radius shrinks by at most 1 − cos 5° ≈ 0.4 % between steps).

use super::accessors::{read_floats, Usage};
use super::check::SkippedChannels;
use crate::frames::Shutter;
use crate::geometry::MotionSteps;
use crate::limits::{one_line, Limits};
use crate::math::{Mat4, Quat, Vec3};
use crate::scene::MalformedPart;
use crate::scene::SceneErrorKind;
use gltf::animation::{Interpolation, Property};
use std::collections::HashMap;
use std::rc::Rc;

/// Every node's local matrix and morph weights at one time.
pub(super) struct Pose {
    /// Local matrices, by node index.
    pub locals: Vec<Mat4>,
    /// Animated morph weights, by node index (`None`: the node's or mesh's own).
    pub weights: Vec<Option<Vec<f32>>>,
}

/// How a channel's values are interpolated between LINEAR keys (glTF 2.0 Appendix C): rotations by slerp,
/// everything else (translations, scales, morph weights, however many) componentwise.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Blend {
    Slerp,
    Lerp,
}

/// One channel, its sampler read: the node and property it drives, and its keys.
struct Channel {
    node: usize,
    property: Property,
    interpolation: Interpolation,
    /// Key times, finite and strictly increasing (shared by the channels whose samplers read one accessor).
    times: Rc<[f32]>,
    /// `elements` floats per key, or for CUBICSPLINE three times as many (in-tangent, value, out-tangent).
    values: Rc<[f32]>,
    /// Floats per key value: 3, 4, or the number of morph targets.
    elements: usize,
}

impl Channel {
    /// The channel's value at `seconds`.
    fn value_at(&self, seconds: f32) -> Vec<f32> {
        let blend = if self.property == Property::Rotation {
            Blend::Slerp
        } else {
            Blend::Lerp
        };
        sample(
            &self.times,
            &self.values,
            self.elements,
            self.interpolation,
            blend,
            seconds,
        )
    }
}

/// Every channel of every animation, read once per load: each accessor is decoded once however many samplers
/// share it, each key-time accessor checked once, and the decoded keys together count against the memory
/// budget. Sampling a pose is then a binary search per channel.
pub(super) struct Animations {
    channels: Vec<Channel>,
    /// Channels that cannot be played (a weights channel on a node without morph targets), skipped.
    pub warnings: Vec<String>,
}

/// Decoded accessors by index and use, and their bytes so far.
struct KeyCache<'a> {
    buffers: &'a [gltf::buffer::Data],
    limits: &'a Limits,
    floats: HashMap<(usize, Usage), Rc<[f32]>>,
    bytes: u64,
}

impl KeyCache<'_> {
    /// The accessor read as `usage`, decoded on first use; `at` names the channel in errors.
    fn read(
        &mut self,
        accessor: &gltf::Accessor,
        usage: Usage,
        at: &str,
    ) -> Result<Rc<[f32]>, SceneErrorKind> {
        let key = (accessor.index(), usage);
        if let Some(floats) = self.floats.get(&key) {
            return Ok(floats.clone());
        }
        let count = accessor.count() as u64;
        let bytes = count.saturating_mul(4 * accessor.dimensions().multiplicity() as u64);
        self.bytes = self.bytes.saturating_add(bytes);
        self.limits
            .check(
                format_args!(
                    "{at}: the animation keys read so far, with accessor {}'s,",
                    key.0
                ),
                self.bytes,
            )
            .map_err(|e| SceneErrorKind::OverLimit(e.to_string()))?;
        let floats: Rc<[f32]> = read_floats(accessor, usage, self.buffers, self.limits)
            .map_err(|e| SceneErrorKind::malformed(MalformedPart::Animation, format!("{at}: {e}")))?
            .into();
        if usage == Usage::KeyTimes
            && (!floats.iter().all(|t| t.is_finite()) || floats.windows(2).any(|w| w[0] >= w[1]))
        {
            return Err(SceneErrorKind::malformed(
                MalformedPart::Animation,
                format!(
                    "{at}: the key times (accessor {}) must be finite and strictly increasing",
                    key.0
                ),
            ));
        }
        self.floats.insert(key, floats.clone());
        Ok(floats)
    }
}

impl Animations {
    /// Reads every channel's sampler (see the type's documentation). A sampler whose output does not hold one
    /// value per key (three for CUBICSPLINE) of its property's size is an error naming the animation, the
    /// channel and the sampler, found from the accessors' counts before either is read.
    /// `skipped` gives the file's channel indices for messages (some channels may have been removed before
    /// parsing).
    pub fn read(
        document: &gltf::Document,
        buffers: &[gltf::buffer::Data],
        limits: &Limits,
        skipped: &SkippedChannels,
    ) -> Result<Self, SceneErrorKind> {
        let mut cache = KeyCache {
            buffers,
            limits,
            floats: HashMap::new(),
            bytes: 0,
        };
        let mut channels = Vec::new();
        let mut warnings = Vec::new();
        for animation in document.animations() {
            let name = match animation.name() {
                Some(n) => format!("animations[{}] '{}'", animation.index(), one_line(n, 120)),
                None => format!("animations[{}]", animation.index()),
            };
            for (kept, channel) in animation.channels().enumerate() {
                let c = skipped.file_index(animation.index(), kept);
                let sampler = channel.sampler();
                let at = format!("{name} channels[{c}] (samplers[{}])", sampler.index());
                let node = channel.target().node();
                let property = channel.target().property();
                let elements = match property {
                    Property::Translation | Property::Scale => 3,
                    Property::Rotation => 4,
                    Property::MorphTargetWeights => match morph_targets(&node) {
                        0 => {
                            warnings.push(format!(
                                "{at} animates the morph weights of node {}, which has no morph targets; skipped",
                                node.index()
                            ));
                            continue;
                        }
                        n => n,
                    },
                };
                check_counts(&sampler, property, elements).map_err(|e| {
                    SceneErrorKind::malformed(MalformedPart::Animation, format!("{at}: {e}"))
                })?;
                let usage = match property {
                    Property::Translation | Property::Scale => Usage::KeyVec3,
                    Property::Rotation => Usage::KeyRotation,
                    Property::MorphTargetWeights => Usage::KeyWeights,
                };
                channels.push(Channel {
                    node: node.index(),
                    property,
                    interpolation: sampler.interpolation(),
                    times: cache.read(&sampler.input(), Usage::KeyTimes, &format!("{at} input"))?,
                    values: cache.read(&sampler.output(), usage, &format!("{at} output"))?,
                    elements,
                });
            }
        }
        Ok(Self { channels, warnings })
    }

    /// The pose of every node at `seconds`: the file's TRS where no channel targets a node, the channels'
    /// values where one does (a later channel on the same property wins).
    pub fn pose_at(&self, document: &gltf::Document, seconds: f32) -> Pose {
        let mut trs: Vec<(Vec3, Quat, Vec3)> = document
            .nodes()
            .map(|n| {
                let (t, r, s) = n.transform().decomposed();
                (Vec3::from(t), Quat::from_array(r), Vec3::from(s))
            })
            .collect();
        let mut animated = vec![false; trs.len()];
        let mut weights = vec![None; trs.len()];
        for channel in &self.channels {
            let value = channel.value_at(seconds);
            let (t, r, s) = &mut trs[channel.node];
            match channel.property {
                Property::Translation => *t = Vec3::from_slice(&value),
                Property::Scale => *s = Vec3::from_slice(&value),
                Property::Rotation => *r = Quat::from_slice(&value).normalize(),
                Property::MorphTargetWeights => weights[channel.node] = Some(value),
            }
            animated[channel.node] |= channel.property != Property::MorphTargetWeights;
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
        Pose { locals, weights }
    }
}

/// The number of morph targets of a node's mesh (its primitives' largest), 0 without a mesh.
fn morph_targets(node: &gltf::Node) -> usize {
    node.mesh().map_or(0, |m| {
        m.primitives()
            .map(|p| p.morph_targets().len())
            .max()
            .unwrap_or(0)
    })
}

/// An animation sampler whose output does not hold one value per key (see [`check_counts`]).
#[derive(Debug, thiserror::Error)]
#[error("the output has {has} elements; {keys} keys of a {interpolation} {what} need {need}")]
struct OutputCountError {
    /// The output accessor's elements.
    has: usize,
    /// The input accessor's keys.
    keys: usize,
    /// The sampler's interpolation (`LINEAR`, `STEP`, `CUBICSPLINE`).
    interpolation: &'static str,
    /// What it animates (`rotation`, `weights for 3 morph targets`).
    what: String,
    /// The elements it needs.
    need: usize,
}

/// Checks from the accessors' counts that a sampler's output holds one value of `elements` floats per key
/// (three per key for CUBICSPLINE: glTF 2.0 §3.11).
fn check_counts(
    sampler: &gltf::animation::Sampler,
    property: Property,
    elements: usize,
) -> Result<(), OutputCountError> {
    let keys = sampler.input().count();
    let interpolation = sampler.interpolation();
    let per_key = if interpolation == Interpolation::CubicSpline {
        3
    } else {
        1
    };
    // A weights output is SCALAR: one accessor element per target; the others one element per value.
    let per_value = if property == Property::MorphTargetWeights {
        elements
    } else {
        1
    };
    let need = keys.saturating_mul(per_key).saturating_mul(per_value);
    let has = sampler.output().count();
    if keys == 0 || has != need {
        let what = match property {
            Property::Translation => "translation".to_owned(),
            Property::Rotation => "rotation".to_owned(),
            Property::Scale => "scale".to_owned(),
            Property::MorphTargetWeights => format!("weights for {elements} morph targets"),
        };
        return Err(OutputCountError {
            has,
            keys,
            interpolation: interpolation_name(interpolation),
            what,
            need,
        });
    }
    Ok(())
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
    /// Every node's world matrix at each step (see `deform::node_worlds`).
    pub worlds: Vec<Vec<Mat4>>,
}

/// Samples the animation at the motion steps of `shutter` around `frame` (see the module documentation for
/// how many); `None` for a shutter that is an instant (or not finite).
pub(super) fn shutter_poses(
    animations: &Animations,
    document: &gltf::Document,
    frame: i64,
    fps: f64,
    shutter: Shutter,
) -> Option<ShutterPoses> {
    let finite = shutter.open.is_finite() && shutter.close.is_finite();
    if !finite || shutter.open >= shutter.close {
        return None;
    }
    let sample = |times: Vec<f32>| -> (Vec<Pose>, Vec<Vec<Mat4>>) {
        let poses: Vec<Pose> = times
            .iter()
            .map(|&t| {
                let seconds = (frame as f64 + t as f64) / fps;
                animations.pose_at(document, seconds as f32)
            })
            .collect();
        let worlds = poses
            .iter()
            .map(|p| super::deform::node_worlds(document, &p.locals))
            .collect();
        (poses, worlds)
    };
    let (_, probes) = sample(shutter.sample_times(PROBES));
    let rotation = |m: &Mat4| Quat::from_mat4(&crate::scene::Camera::rigid(m)).normalize();
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
    let (poses, worlds) = sample(shutter.sample_times(count as usize));
    Some(ShutterPoses {
        steps: MotionSteps {
            open: shutter.open,
            close: shutter.close,
            count,
        },
        poses,
        worlds,
    })
}

/// An interpolation as glTF spells it.
fn interpolation_name(interpolation: Interpolation) -> &'static str {
    match interpolation {
        Interpolation::Linear => "LINEAR",
        Interpolation::Step => "STEP",
        Interpolation::CubicSpline => "CUBICSPLINE",
    }
}

/// The value of a sampler with `elements` floats per key at `t` (glTF 2.0 Appendix C). `values` holds one
/// element per key, or for CUBICSPLINE three (in-tangent, value, out-tangent); LINEAR keys are blended by
/// `blend`.
fn sample(
    times: &[f32],
    values: &[f32],
    elements: usize,
    interpolation: Interpolation,
    blend: Blend,
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
        Interpolation::Linear if blend == Blend::Slerp => {
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
        let at = |i, t| sample(&times, &values, 1, i, Blend::Lerp, t)[0];
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
        let q = Quat::from_slice(&sample(
            &[0.0, 1.0],
            &values,
            4,
            Interpolation::Linear,
            Blend::Slerp,
            0.5,
        ));
        let want = Quat::from_rotation_y(std::f32::consts::FRAC_PI_4);
        assert!(q.angle_between(want) < 1e-5, "{q} vs {want}");
    }

    #[test]
    fn four_morph_weights_are_lerped_not_slerped() {
        let values = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0];
        let w = sample(
            &[0.0, 1.0],
            &values,
            4,
            Interpolation::Linear,
            Blend::Lerp,
            0.5,
        );
        assert_eq!(w, [0.5, 0.5, 0.0, 0.0]);
    }

    #[test]
    fn cubic_spline_is_the_hermite_curve() {
        // Keys 0 → 1 over 2 s with out-tangent 0.5 and in-tangent 0.5 (per second): the cubic with p(0) = 0,
        // p(2) = 1, p'(0) = p'(2) = 0.5 is the line p(t) = t/2; with zero tangents it is the smoothstep.
        let values = [0.0, 0.0, 0.5, 0.5, 1.0, 0.0];
        let p = sample(
            &[0.0, 2.0],
            &values,
            1,
            Interpolation::CubicSpline,
            Blend::Lerp,
            0.5,
        )[0];
        assert!((p - 0.25).abs() < 1e-6, "{p}");
        let flat = [0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let p = sample(
            &[0.0, 2.0],
            &flat,
            1,
            Interpolation::CubicSpline,
            Blend::Lerp,
            0.5,
        )[0];
        let s: f32 = 0.25;
        assert!((p - (3.0 * s * s - 2.0 * s * s * s)).abs() < 1e-6, "{p}");
    }
}
