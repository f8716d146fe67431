//! Scene-file parameters, below both the loaders (`scene`) and the media (`volume`): tables of keys that
//! declare each parameter once (name, type, default, meaning, and where USD finds it), the values a loader reads
//! for them, and the JSON readers that glTF's `extras` and the volume declarations share.
//!
//! A declaration (a VDB volume, a mesh's interior medium) lists its keys in a `&[ParamKey]` table: the table
//! is what the loaders read through (glTF from a JSON object with [`JsonParams`], USD from a prim's `nimbus:`
//! attributes) and what the key tables of docs/reference.md show ([`markdown_table`]; a test keeps them in agreement).

use crate::math::Rgb;
use std::fmt;

/// The type of a parameter's value, and the check every loader applies when reading it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ParamType {
    /// A finite number.
    Number,
    /// A finite number ≥ 0.
    NonNegative,
    /// Three finite numbers ≥ 0 (`[r, g, b]`; a USD `color3f`).
    Rgb,
    /// A number (grey) or three numbers (`[r, g, b]`).
    GreyOrRgb,
    /// A string (a file or grid name; a USD `string`, `token` or `asset`).
    Text,
    /// One of the listed names.
    Choice(&'static [&'static str]),
    /// A nested object with its own keys (glTF only).
    Object(&'static [ParamKey]),
}

impl ParamType {
    /// How the type reads in messages and documentation ("a number", "one of ...").
    pub fn describe(self) -> String {
        match self {
            Self::Number => "a number".into(),
            Self::NonNegative => "a non-negative number".into(),
            Self::Rgb => "[r, g, b] (three non-negative numbers)".into(),
            Self::GreyOrRgb => "a number or [r, g, b]".into(),
            Self::Text => "a string".into(),
            Self::Choice(names) => format!("one of {}", names.join(", ")),
            Self::Object(_) => "an object".into(),
        }
    }
}

/// The default of a parameter, as the code applies it and the documentation shows it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ParamDefault {
    /// The key must be given.
    Required,
    /// Absent means "none" (the feature it enables is off).
    Unset,
    /// A number.
    Number(f64),
    /// An RGB triple.
    Rgb([f32; 3]),
    /// A string or a choice.
    Text(&'static str),
}

impl fmt::Display for ParamDefault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Required => write!(f, "required"),
            Self::Unset => write!(f, "none"),
            Self::Number(x) => write!(f, "{x}"),
            Self::Rgb([r, g, b]) => write!(f, "[{r}, {g}, {b}]"),
            Self::Text(s) => write!(f, "`\"{s}\"`"),
        }
    }
}

/// Where a USD stage gives a parameter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UsdBinding {
    /// The prim attribute `nimbus:<name>`.
    Attribute,
    /// Elsewhere in the stage (the text says where), or nowhere (USD has no such declaration).
    Elsewhere(&'static str),
}

/// One key of a parameter table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamKey {
    /// The key: glTF JSON key, and USD attribute `nimbus:<name>` where [`UsdBinding::Attribute`].
    pub name: &'static str,
    /// Its type.
    pub ty: ParamType,
    /// Its default.
    pub default: ParamDefault,
    /// What it means.
    pub doc: &'static str,
    /// Where USD gives it.
    pub usd: UsdBinding,
}

/// A value read for a key, already checked against the key's [`ParamType`].
#[derive(Clone, Debug, PartialEq)]
pub enum ParamValue {
    /// [`ParamType::Number`] or [`ParamType::NonNegative`].
    Number(f64),
    /// [`ParamType::Rgb`] or [`ParamType::GreyOrRgb`] (a grey number is splatted).
    Rgb(Rgb),
    /// [`ParamType::Text`] or [`ParamType::Choice`] (one of the names).
    Text(String),
}

/// A parameter that is missing, of the wrong type, or out of range. `key` is the name as the scene file spells
/// it (`density_scale` in glTF, `nimbus:density_scale` in USD).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ParamError {
    /// A required key is absent.
    #[error("'{key}' is required")]
    Missing {
        /// The key.
        key: String,
    },
    /// The value has the wrong type.
    #[error("'{key}' must be {expected}")]
    WrongType {
        /// The key.
        key: String,
        /// What it must be ([`ParamType::describe`]).
        expected: String,
    },
    /// A name that is not one of the key's choices.
    #[error("'{key}' {value:?} is not one of {}", choices.join(", "))]
    UnknownChoice {
        /// The key.
        key: String,
        /// The name given.
        value: String,
        /// The names the key accepts.
        choices: &'static [&'static str],
    },
    /// The value is of the right type but outside the key's range.
    #[error("'{key}' {value} must {constraint}")]
    OutOfRange {
        /// The key.
        key: String,
        /// The value as given.
        value: String,
        /// The range, as a phrase ("lie in (-1, 1)").
        constraint: &'static str,
    },
    /// The scene file could not give the value (an unreadable USD attribute).
    #[error("'{key}' cannot be read: {message}")]
    Unreadable {
        /// The key.
        key: String,
        /// The reader's message.
        message: String,
    },
}

/// Where a loader reads a table's values from: a glTF JSON object, a USD prim.
pub trait ParamSource {
    /// The value of `key` converted to its type, `None` when the file does not give it, or an error when it is
    /// of the wrong type. Keys of [`ParamType::Object`] are read by the source's own means
    /// ([`JsonParams::nested`]).
    fn get(&self, key: &ParamKey) -> Result<Option<ParamValue>, ParamError>;

    /// The name of `key` as the file spells it, for messages.
    fn spelling(&self, key: &ParamKey) -> String {
        key.name.to_owned()
    }
}

/// Typed reads of one key through a source.
pub trait ParamRead: ParamSource {
    /// A number key, in double precision (seeds, values checked before rounding).
    fn number_f64(&self, key: &ParamKey) -> Result<Option<f64>, ParamError> {
        Ok(match self.get(key)? {
            Some(ParamValue::Number(x)) => Some(x),
            Some(_) => return Err(self.wrong_type(key)),
            None => None,
        })
    }

    /// A number key.
    fn number(&self, key: &ParamKey) -> Result<Option<f32>, ParamError> {
        Ok(self.number_f64(key)?.map(|x| x as f32))
    }

    /// An RGB key (or grey number).
    fn rgb(&self, key: &ParamKey) -> Result<Option<Rgb>, ParamError> {
        Ok(match self.get(key)? {
            Some(ParamValue::Rgb(c)) => Some(c),
            Some(_) => return Err(self.wrong_type(key)),
            None => None,
        })
    }

    /// A text or choice key.
    fn text(&self, key: &ParamKey) -> Result<Option<String>, ParamError> {
        Ok(match self.get(key)? {
            Some(ParamValue::Text(s)) => Some(s),
            Some(_) => return Err(self.wrong_type(key)),
            None => None,
        })
    }

    /// A required text key.
    fn required_text(&self, key: &ParamKey) -> Result<String, ParamError> {
        self.text(key)?.ok_or_else(|| ParamError::Missing {
            key: self.spelling(key),
        })
    }

    /// The error for a value that is not of `key`'s type.
    fn wrong_type(&self, key: &ParamKey) -> ParamError {
        ParamError::WrongType {
            key: self.spelling(key),
            expected: key.ty.describe(),
        }
    }
}

impl<S: ParamSource + ?Sized> ParamRead for S {}

/// A glTF JSON object (`extras.nimbus_volume`, `extras.nimbus_medium`) as a parameter source.
#[derive(Clone, Debug)]
pub struct JsonParams<'a> {
    value: &'a serde_json::Value,
    /// The path of a nested object's keys in messages (`"noise."`), empty at the top.
    prefix: String,
}

impl<'a> JsonParams<'a> {
    /// The keys of the JSON object `value`.
    pub fn new(value: &'a serde_json::Value) -> Self {
        Self {
            value,
            prefix: String::new(),
        }
    }

    /// The nested object of an [`ParamType::Object`] key, if given.
    pub fn nested(&self, key: &ParamKey) -> Result<Option<JsonParams<'a>>, ParamError> {
        match self.value.get(key.name) {
            None => Ok(None),
            Some(v) if v.is_object() => Ok(Some(JsonParams {
                value: v,
                prefix: format!("{}.", self.spelling(key)),
            })),
            Some(_) => Err(self.wrong_type(key)),
        }
    }
}

impl ParamSource for JsonParams<'_> {
    fn spelling(&self, key: &ParamKey) -> String {
        format!("{}{}", self.prefix, key.name)
    }

    fn get(&self, key: &ParamKey) -> Result<Option<ParamValue>, ParamError> {
        let Some(v) = self.value.get(key.name) else {
            return Ok(None);
        };
        if let Some(x) = beyond_single_precision(v) {
            return Err(ParamError::OutOfRange {
                key: self.spelling(key),
                value: format!("{x:e}"),
                constraint: "fit single precision (magnitude at most 3.4e38)",
            });
        }
        let value = match key.ty {
            ParamType::Number => finite(v).map(ParamValue::Number),
            ParamType::NonNegative => finite(v).filter(|x| *x >= 0.0).map(ParamValue::Number),
            ParamType::Rgb => parse_rgb(v).map(ParamValue::Rgb),
            ParamType::GreyOrRgb => match finite(v) {
                Some(x) => Some(ParamValue::Rgb(Rgb::splat(x as f32))),
                None => parse_rgb(v).map(ParamValue::Rgb),
            },
            ParamType::Text => v.as_str().map(|s| ParamValue::Text(s.to_owned())),
            ParamType::Choice(names) => match v.as_str() {
                Some(s) if names.contains(&s) => Some(ParamValue::Text(s.to_owned())),
                Some(s) => {
                    return Err(ParamError::UnknownChoice {
                        key: self.spelling(key),
                        value: s.to_owned(),
                        choices: names,
                    })
                }
                None => None,
            },
            ParamType::Object(_) => return Err(self.wrong_type(key)),
        };
        value.map(Some).ok_or_else(|| self.wrong_type(key))
    }
}

/// The first number in `v` (a number or an array of them) whose magnitude no `f32` holds: such a value would
/// become infinite where the renderer stores it, and make tracking endless.
fn beyond_single_precision(v: &serde_json::Value) -> Option<f64> {
    let too_large = |x: &serde_json::Value| x.as_f64().filter(|x| x.abs() > f32::MAX as f64);
    match v {
        serde_json::Value::Array(items) => items.iter().find_map(too_large),
        _ => too_large(v),
    }
}

/// A finite JSON number.
fn finite(v: &serde_json::Value) -> Option<f64> {
    v.as_f64().filter(|x| x.is_finite())
}

/// Parses `[r, g, b]` with finite non-negative components.
pub fn parse_rgb(value: &serde_json::Value) -> Option<Rgb> {
    let a = value.as_array()?;
    if a.len() != 3 {
        return None;
    }
    let mut c = [0.0f32; 3];
    for (i, v) in a.iter().enumerate() {
        c[i] = v.as_f64().filter(|v| v.is_finite() && *v >= 0.0)? as f32;
    }
    Some(Rgb::from(c))
}

/// The Markdown table of `keys` that docs/reference.md shows: key, type, default, USD attribute, meaning. Keys of
/// nested objects follow their parent as `parent.key`.
pub fn markdown_table(keys: &[ParamKey]) -> String {
    let mut out =
        String::from("| key | value | default | USD | meaning |\n|---|---|---|---|---|\n");
    fn rows(out: &mut String, prefix: &str, keys: &[ParamKey]) {
        for k in keys {
            let usd = match k.usd {
                UsdBinding::Attribute => format!("`nimbus:{}`", k.name),
                UsdBinding::Elsewhere(s) => s.to_owned(),
            };
            out.push_str(&format!(
                "| `{prefix}{}` | {} | {} | {usd} | {} |\n",
                k.name,
                k.ty.describe(),
                k.default,
                k.doc
            ));
            if let ParamType::Object(inner) = k.ty {
                rows(out, &format!("{prefix}{}.", k.name), inner);
            }
        }
    }
    rows(&mut out, "", keys);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    const N: ParamKey = ParamKey {
        name: "n",
        ty: ParamType::NonNegative,
        default: ParamDefault::Number(1.0),
        doc: "",
        usd: UsdBinding::Attribute,
    };
    const C: ParamKey = ParamKey {
        name: "c",
        ty: ParamType::GreyOrRgb,
        default: ParamDefault::Rgb([1.0; 3]),
        doc: "",
        usd: UsdBinding::Attribute,
    };
    const K: ParamKey = ParamKey {
        name: "k",
        ty: ParamType::Choice(&["a", "b"]),
        default: ParamDefault::Text("a"),
        doc: "",
        usd: UsdBinding::Attribute,
    };

    #[test]
    fn json_values_are_checked_against_their_type() {
        let v = json!({"n": 2, "c": 0.5, "k": "b"});
        let p = JsonParams::new(&v);
        assert_eq!(p.number(&N), Ok(Some(2.0)));
        assert_eq!(p.rgb(&C), Ok(Some(Rgb::splat(0.5))));
        assert_eq!(p.text(&K), Ok(Some("b".into())));
        let v = json!({"n": -1, "c": [1, 2], "k": "z"});
        let p = JsonParams::new(&v);
        for key in [N, C] {
            assert!(
                matches!(p.get(&key), Err(ParamError::WrongType { .. })),
                "{}",
                key.name
            );
        }
        assert_eq!(
            p.get(&K).unwrap_err().to_string(),
            "'k' \"z\" is not one of a, b"
        );
        assert_eq!(JsonParams::new(&json!({})).number(&N), Ok(None));
        assert_eq!(
            parse_rgb(&json!([1, 0, 2.5])),
            Some(Rgb::new(1.0, 0.0, 2.5))
        );
        assert_eq!(parse_rgb(&json!([1, -1, 2])), None);
    }

    #[test]
    fn numbers_beyond_single_precision_are_out_of_range() {
        // 1e308 is a finite f64 but an infinite f32: a noise max_density of 1e308 made tracking endless.
        for v in [
            json!({"n": 1e308, "c": 1}),
            json!({"n": 1, "c": [1, 1e39, 1]}),
        ] {
            let p = JsonParams::new(&v);
            let err = p.number(&N).and_then(|_| p.rgb(&C)).unwrap_err();
            assert!(matches!(err, ParamError::OutOfRange { .. }), "{err}");
            assert!(err.to_string().contains("single precision"), "{err}");
        }
    }
}
