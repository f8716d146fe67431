//! The method configurations `nimbus converge` compares: overrides applied to a scene after loading.

use crate::volume::grid::ShadowEstimator;
use crate::volume::majorant::MajorantKind;
use crate::volume::VolumeSpec;
use std::fmt;
use std::str::FromStr;

/// One way of rendering the same scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// The scene as declared.
    Default,
    /// Delta tracking under one global majorant in every grid medium.
    GlobalMajorant,
    /// A fixed 16³ grid of majorants in every grid medium.
    Grid16Majorant,
    /// The adaptive two-level majorant hierarchy in every grid medium.
    AdaptiveMajorant,
    /// Ratio tracking for shadow rays in every grid medium.
    RatioShadow,
    /// Residual ratio tracking for shadow rays in every grid medium.
    ResidualRatioShadow,
    /// No multiple importance sampling at medium scattering events (light sampling only).
    NoMediaMis,
}

impl Method {
    /// Every method, in the order charts and tables list them.
    pub const ALL: [Method; 7] = [
        Method::Default,
        Method::GlobalMajorant,
        Method::Grid16Majorant,
        Method::AdaptiveMajorant,
        Method::RatioShadow,
        Method::ResidualRatioShadow,
        Method::NoMediaMis,
    ];

    /// The name used on the command line and in outputs.
    pub fn name(self) -> &'static str {
        match self {
            Method::Default => "default",
            Method::GlobalMajorant => "global-majorant",
            Method::Grid16Majorant => "grid16-majorant",
            Method::AdaptiveMajorant => "adaptive-majorant",
            Method::RatioShadow => "ratio-shadow",
            Method::ResidualRatioShadow => "residual-ratio-shadow",
            Method::NoMediaMis => "no-media-mis",
        }
    }

    /// Parses a comma-separated list of method names (duplicates removed, order kept).
    pub fn parse_list(list: &str) -> Result<Vec<Method>, MethodError> {
        let mut methods = Vec::new();
        for name in list.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            let m: Method = name.parse()?;
            if !methods.contains(&m) {
                methods.push(m);
            }
        }
        if methods.is_empty() {
            return Err(MethodError::NoneNamed);
        }
        Ok(methods)
    }

    internal! {
        /// Changes a VDB volume's declaration as this method requires.
        pub fn apply_to_volume(self, spec: &mut VolumeSpec) {
            match self {
                Method::GlobalMajorant => spec.majorant = Some(MajorantKind::Global),
                Method::Grid16Majorant => spec.majorant = Some(MajorantKind::Grid16),
                Method::AdaptiveMajorant => spec.majorant = Some(MajorantKind::Adaptive),
                Method::RatioShadow => spec.shadow_estimator = ShadowEstimator::Ratio,
                Method::ResidualRatioShadow => {
                    spec.shadow_estimator = ShadowEstimator::ResidualRatio
                }
                Method::Default | Method::NoMediaMis => {}
            }
        }
    }

    /// Whether the method changes VDB volumes' declarations (and so needs a scene with at least one).
    pub fn changes_volumes(self) -> bool {
        !matches!(self, Method::Default | Method::NoMediaMis)
    }

    /// Whether the path tracer uses MIS at medium scattering events.
    pub fn media_mis(self) -> bool {
        self != Method::NoMediaMis
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Method {
    type Err = MethodError;

    fn from_str(s: &str) -> Result<Self, MethodError> {
        Method::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| MethodError::Unknown(s.to_owned()))
    }
}

/// A method name that does not parse ([`Method::from_str`], [`Method::parse_list`]).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum MethodError {
    /// A name that is no method's.
    #[error("unknown method '{0}' (one of {names})", names = Method::ALL.map(Method::name).join(", "))]
    Unknown(String),
    /// A list that names no method.
    #[error("no method named")]
    NoneNamed,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_lists_parse() {
        for m in Method::ALL {
            assert_eq!(m.name().parse::<Method>(), Ok(m));
        }
        assert_eq!(
            Method::parse_list("default, no-media-mis,default").unwrap(),
            vec![Method::Default, Method::NoMediaMis]
        );
        assert!(Method::parse_list("default,bogus").is_err());
        assert!(Method::parse_list(" , ").is_err());
    }

    #[test]
    fn overrides_change_the_volume() {
        let mut spec = VolumeSpec::new("v", "a.vdb".into(), crate::math::Mat4::IDENTITY);
        Method::GlobalMajorant.apply_to_volume(&mut spec);
        Method::ResidualRatioShadow.apply_to_volume(&mut spec);
        assert_eq!(spec.majorant, Some(MajorantKind::Global));
        assert_eq!(spec.shadow_estimator, ShadowEstimator::ResidualRatio);
        assert!(!Method::NoMediaMis.media_mis() && Method::Default.media_mis());
    }
}
