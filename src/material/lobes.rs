//! Lobe classes for light-path AOVs: every BSDF lobe is diffuse, glossy or transmission, and the BSDF's value,
//! its samples and its colours can be split by class (Cycles' and Arnold's light-path passes).
//!
//! Classification rule:
//! - **diffuse**: [`super::Lambert`] and the diffuse base of the glTF metallic-roughness model;
//! - **glossy**: the GGX or mirror specular reflection of the metallic-roughness model (its dielectric
//!   specular and its metal), the clear coat, the sheen, and the reflection of a dielectric interface, rough or
//!   smooth (in the transmissive part of [`super::GltfPbr`] and in a pure [`super::Dielectric`]);
//! - **transmission**: the refraction of a dielectric interface, rough or smooth, and the Lambertian diffuse
//!   transmission of `KHR_materials_diffuse_transmission`.
//!
//! Seen from below a transmissive surface (`wo.z < 0`, inside the solid) the same rule applies: internal
//! reflection is glossy, refraction transmission. So a dielectric's glossy light always leaves on `wo`'s side and
//! its transmission on the other side; the other lobes of the opaque part reflect.
//!
//! How the integrator uses it: at the first surface hit, [`super::Bsdf::eval_split`] splits next-event
//! estimation by class; a non-delta sampled direction splits the light found further along the path by each
//! class's share of `f` per channel ([`LobeSplit::shares`]); a delta sample belongs wholly to its lobe's class
//! ([`super::BsdfSample::class`]). [`super::Bsdf::colors`] gives each class's colour at the first hit, by which
//! the light passes are divided, so that `(direct + indirect) × color` rebuilds each class's light.

use crate::math::Rgb;
use std::ops::{Add, AddAssign, Mul};

/// The class a BSDF lobe's light is counted under in the light-path AOVs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LobeClass {
    /// Diffuse reflection: `super::Lambert` and the diffuse base of the glTF metallic-roughness model.
    Diffuse,
    /// Specular and glossy reflection: the metallic-roughness model's specular layer (dielectric and metal,
    /// GGX or mirror), the clear coat, the sheen, and a dielectric interface's reflection (rough or smooth,
    /// from either side).
    Glossy,
    /// Refraction through a dielectric interface (rough or smooth, from either side), and the diffuse
    /// transmission of `KHR_materials_diffuse_transmission`.
    Transmission,
}

impl LobeClass {
    /// Every class, in the order diffuse, glossy, transmission.
    pub const ALL: [LobeClass; 3] = [
        LobeClass::Diffuse,
        LobeClass::Glossy,
        LobeClass::Transmission,
    ];

    /// The lower-case name used in AOV names: "diffuse", "glossy" or "transmission".
    pub fn name(self) -> &'static str {
        match self {
            LobeClass::Diffuse => "diffuse",
            LobeClass::Glossy => "glossy",
            LobeClass::Transmission => "transmission",
        }
    }
}

/// One RGB value per lobe class: a BSDF value, a colour or a contribution split by class.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LobeSplit {
    /// The diffuse class's part.
    pub diffuse: Rgb,
    /// The glossy class's part.
    pub glossy: Rgb,
    /// The transmission class's part.
    pub transmission: Rgb,
}

impl LobeSplit {
    /// Zero in every class.
    pub const ZERO: LobeSplit = LobeSplit {
        diffuse: Rgb::ZERO,
        glossy: Rgb::ZERO,
        transmission: Rgb::ZERO,
    };

    /// `value` in `class`, zero in the others.
    pub fn only(class: LobeClass, value: Rgb) -> Self {
        let mut split = Self::ZERO;
        *split.get_mut(class) = value;
        split
    }

    /// The sum over the classes.
    pub fn total(&self) -> Rgb {
        self.diffuse + self.glossy + self.transmission
    }

    /// The part of `class`.
    pub fn get(&self, class: LobeClass) -> Rgb {
        match class {
            LobeClass::Diffuse => self.diffuse,
            LobeClass::Glossy => self.glossy,
            LobeClass::Transmission => self.transmission,
        }
    }

    /// The part of `class`, mutably.
    pub fn get_mut(&mut self, class: LobeClass) -> &mut Rgb {
        match class {
            LobeClass::Diffuse => &mut self.diffuse,
            LobeClass::Glossy => &mut self.glossy,
            LobeClass::Transmission => &mut self.transmission,
        }
    }

    /// Each class's fraction of the total, per channel: `part_k / total` where the total is positive, else 0.
    /// For a split BSDF value these are the weights `f_k(wo, wi) / f(wo, wi)` by which a sampled direction's
    /// later light is shared between the classes; they sum to 1 in every channel the total is positive.
    pub fn shares(&self) -> LobeSplit {
        let total = self.total();
        let share = |part: Rgb| Rgb::select(total.cmpgt(Rgb::ZERO), part / total, Rgb::ZERO);
        LobeSplit {
            diffuse: share(self.diffuse),
            glossy: share(self.glossy),
            transmission: share(self.transmission),
        }
    }
}

impl Add for LobeSplit {
    type Output = LobeSplit;

    /// Class-wise sum.
    fn add(self, rhs: LobeSplit) -> LobeSplit {
        LobeSplit {
            diffuse: self.diffuse + rhs.diffuse,
            glossy: self.glossy + rhs.glossy,
            transmission: self.transmission + rhs.transmission,
        }
    }
}

impl AddAssign for LobeSplit {
    /// Class-wise sum in place.
    fn add_assign(&mut self, rhs: LobeSplit) {
        *self = *self + rhs;
    }
}

impl Mul<Rgb> for LobeSplit {
    type Output = LobeSplit;

    /// Every class multiplied channel-wise by `rhs` (e.g. a path throughput).
    fn mul(self, rhs: Rgb) -> LobeSplit {
        LobeSplit {
            diffuse: self.diffuse * rhs,
            glossy: self.glossy * rhs,
            transmission: self.transmission * rhs,
        }
    }
}

impl Mul<f32> for LobeSplit {
    type Output = LobeSplit;

    /// Every class scaled by `rhs`.
    fn mul(self, rhs: f32) -> LobeSplit {
        self * Rgb::splat(rhs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn example() -> LobeSplit {
        LobeSplit {
            diffuse: Rgb::new(1.0, 0.0, 2.0),
            glossy: Rgb::new(3.0, 0.0, 0.5),
            transmission: Rgb::new(0.0, 0.0, 1.5),
        }
    }

    #[test]
    fn names_and_accessors_agree() {
        let names: Vec<_> = LobeClass::ALL.iter().map(|c| c.name()).collect();
        assert_eq!(names, ["diffuse", "glossy", "transmission"]);
        let s = example();
        assert_eq!(s.get(LobeClass::Diffuse), s.diffuse);
        assert_eq!(s.get(LobeClass::Glossy), s.glossy);
        assert_eq!(s.get(LobeClass::Transmission), s.transmission);
        for class in LobeClass::ALL {
            let v = Rgb::new(0.1, 0.2, 0.3);
            let only = LobeSplit::only(class, v);
            assert_eq!(only.total(), v);
            for other in LobeClass::ALL {
                let expected = if other == class { v } else { Rgb::ZERO };
                assert_eq!(only.get(other), expected);
            }
            let mut m = s;
            *m.get_mut(class) = v;
            assert_eq!(m.get(class), v);
            assert_eq!(m.total(), s.total() - s.get(class) + v);
        }
        assert_eq!(LobeSplit::default(), LobeSplit::ZERO);
        assert_eq!(s.total(), Rgb::new(4.0, 0.0, 4.0));
    }

    #[test]
    fn arithmetic_is_class_wise() {
        let s = example();
        let doubled = s * 2.0;
        let mut sum = s;
        sum += s;
        assert_eq!(doubled, sum);
        assert_eq!(s + s, sum);
        let scaled = s * Rgb::new(1.0, 5.0, 0.5);
        assert_eq!(scaled.diffuse, Rgb::new(1.0, 0.0, 1.0));
        assert_eq!(scaled.glossy, Rgb::new(3.0, 0.0, 0.25));
        assert_eq!(scaled.transmission, Rgb::new(0.0, 0.0, 0.75));
    }

    #[test]
    fn shares_sum_to_one_where_there_is_light() {
        let sh = example().shares();
        assert_eq!(sh.diffuse, Rgb::new(0.25, 0.0, 0.5));
        assert_eq!(sh.glossy, Rgb::new(0.75, 0.0, 0.125));
        assert_eq!(sh.transmission, Rgb::new(0.0, 0.0, 0.375));
        // The empty green channel shares nothing rather than dividing by zero.
        assert_eq!(sh.total(), Rgb::new(1.0, 0.0, 1.0));
        let tiny = LobeSplit::only(LobeClass::Glossy, Rgb::splat(1e-40)).shares();
        assert_eq!(tiny.glossy, Rgb::ONE);
    }
}
