//! Scene-file parameters, below both the loaders (`scene`) and the media (`volume`): tables of keys that
//! declare each parameter once (name, type, default, meaning, and where USD finds it), the values a loader reads
//! for them, and the JSON readers that glTF's `extras` and the volume declarations share.
//!
//! A declaration (a VDB volume, a mesh's interior medium) lists its keys in a `&[ParamKey]` table: the table
//! is what the loaders read through (glTF from a JSON object with `JsonParams`, USD from a prim's `nimbus:`
//! attributes) and what the key tables of docs/reference.md show (`markdown_table`; a test keeps them in agreement).

use crate::math::Rgb;
use std::fmt;

internal! {
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

internal! {
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
}

impl ParamDefault {
    /// The default as the value a scene file would give for it; `None` for [`ParamDefault::Required`] and
    /// [`ParamDefault::Unset`] (no value stands for them).
    pub fn value(self) -> Option<ParamValue> {
        match self {
            Self::Required | Self::Unset => None,
            Self::Number(x) => Some(ParamValue::Number(x)),
            Self::Rgb(c) => Some(ParamValue::Rgb(Rgb::from_array(c))),
            Self::Text(s) => Some(ParamValue::Text(s.to_owned())),
        }
    }
}

/// A key's default as a scene file spells it (a JSON value), `None` where no value stands for it (required,
/// unset): for tests that give each default explicitly.
#[cfg(test)]
pub(crate) fn default_as_json(key: &ParamKey) -> Option<serde_json::Value> {
    Some(match key.default.value()? {
        ParamValue::Number(x) => serde_json::json!(x),
        ParamValue::Rgb(c) => serde_json::json!(c.to_array()),
        ParamValue::Text(s) => serde_json::json!(s),
    })
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

internal! {
    /// Where a USD stage gives a parameter.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub enum UsdBinding {
        /// The prim attribute `nimbus:<name>`.
        Attribute,
        /// Elsewhere in the stage (the text says where), or nowhere (USD has no such declaration).
        Elsewhere(&'static str),
    }
}

internal! {
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
}

internal! {
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
        /// What it must be (`ParamType::describe`).
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

internal! {
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
}

internal! {
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

        /// A number key in double precision, else the key's table default: a key's default is applied by this
        /// one reading of its table ([`ParamKey::default`]). [`ParamError::Missing`] when neither is there.
        fn number_f64_or_default(&self, key: &ParamKey) -> Result<f64, ParamError> {
            match self.number_f64(key)? {
                Some(x) => Ok(x),
                None => TableDefaults
                    .number_f64(key)?
                    .ok_or_else(|| self.missing(key)),
            }
        }

        /// An RGB key (or grey number), else the key's table default; [`ParamError::Missing`] when neither is
        /// there.
        fn rgb_or_default(&self, key: &ParamKey) -> Result<Rgb, ParamError> {
            match self.rgb(key)? {
                Some(c) => Ok(c),
                None => TableDefaults.rgb(key)?.ok_or_else(|| self.missing(key)),
            }
        }

        /// A required text key.
        fn required_text(&self, key: &ParamKey) -> Result<String, ParamError> {
            self.text(key)?.ok_or_else(|| self.missing(key))
        }

        /// The error for a key that is absent and has no default.
        fn missing(&self, key: &ParamKey) -> ParamError {
            ParamError::Missing {
                key: self.spelling(key),
            }
        }

        /// The error for a value that is not of `key`'s type.
        fn wrong_type(&self, key: &ParamKey) -> ParamError {
            ParamError::WrongType {
                key: self.spelling(key),
                expected: key.ty.describe(),
            }
        }
    }
}

impl<S: ParamSource + ?Sized> ParamRead for S {}

internal! {
    /// The key tables' own defaults as a parameter source: every key gives its [`ParamKey::default`] (as
    /// [`ParamDefault::value`]), so that a declaration's defaults are applied by the same code that applies the
    /// values a file gives.
    #[derive(Clone, Copy, Debug)]
    pub struct TableDefaults;
}

impl ParamSource for TableDefaults {
    fn get(&self, key: &ParamKey) -> Result<Option<ParamValue>, ParamError> {
        Ok(key.default.value())
    }
}

internal! {
    /// A glTF JSON object (`extras.nimbus_volume`, `extras.nimbus_medium`) as a parameter source.
    #[derive(Clone, Debug)]
    pub struct JsonParams<'a> {
        value: &'a serde_json::Value,
        /// The path of a nested object's keys in messages (`"noise."`), empty at the top.
        prefix: String,
    }
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

internal! {
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
}

internal! {
    /// A key a scene file gives that no table declares (a misspelt `"densty_scale"`): the renderer would ignore
    /// it, so the loaders warn, or refuse it under `--strict`, as pbrt-v4 reports unused parameters.
    #[derive(Clone, Debug, PartialEq, Eq)]
    pub struct UnknownKey {
        /// The key as the file spells it (`noise.sead` for a nested object's key).
        pub key: String,
        /// The declared key closest to it, when one is close enough to be a likely misspelling.
        pub closest: Option<String>,
    }
}

impl UnknownKey {
    /// The suggestion that follows the message: ` (did you mean 'density_scale'?)`, or nothing.
    pub fn hint(&self) -> String {
        self.closest
            .as_ref()
            .map_or_else(String::new, |c| format!(" (did you mean '{c}'?)"))
    }
}

impl fmt::Display for UnknownKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "unknown key '{}'", self.key)
    }
}

internal! {
    /// The keys of the JSON object `value` that start with `prefix` and are not among `names` (the `nimbus_*` keys
    /// of an `extras` object, which also holds other tools' keys), in alphabetical order.
    pub fn unknown_json_names(
        value: &serde_json::Value,
        names: &[&'static str],
        prefix: &str,
    ) -> Vec<UnknownKey> {
        let Some(object) = value.as_object() else {
            return Vec::new();
        };
        object
            .keys()
            .filter(|key| key.starts_with(prefix) && !names.contains(&key.as_str()))
            .map(|key| UnknownKey {
                key: key.clone(),
                closest: closest_name(key, names.iter().copied()).map(str::to_owned),
            })
            .collect()
    }
}

internal! {
    /// The keys of the JSON object `value` that `keys` does not declare, nested objects' keys included (a value
    /// that is not an object has none), in alphabetical order.
    pub fn unknown_json_keys(value: &serde_json::Value, keys: &[ParamKey]) -> Vec<UnknownKey> {
        let mut found = Vec::new();
        collect_unknown(value, keys, "", &mut found);
        found
    }
}

fn collect_unknown(
    value: &serde_json::Value,
    keys: &[ParamKey],
    prefix: &str,
    found: &mut Vec<UnknownKey>,
) {
    let Some(object) = value.as_object() else {
        return;
    };
    for (name, v) in object {
        match keys.iter().find(|k| k.name == name) {
            Some(ParamKey {
                ty: ParamType::Object(inner),
                ..
            }) => collect_unknown(v, inner, &format!("{prefix}{name}."), found),
            Some(_) => {}
            None => found.push(UnknownKey {
                key: format!("{prefix}{name}"),
                closest: closest_name(name, keys.iter().map(|k| k.name)).map(str::to_owned),
            }),
        }
    }
}

internal! {
    /// The name among `names` closest to `given` in edit distance, if within a third of its length (at least 1,
    /// at most 3 edits): a likely misspelling rather than another word.
    pub fn closest_name<'n>(
        given: &str,
        names: impl IntoIterator<Item = &'n str>,
    ) -> Option<&'n str> {
        let allowed = (given.chars().count() / 3).clamp(1, 3);
        names
            .into_iter()
            .map(|name| (edit_distance(given, name), name))
            .filter(|&(d, _)| d <= allowed)
            .min_by_key(|&(d, _)| d)
            .map(|(_, name)| name)
    }
}

/// The Levenshtein distance between `a` and `b` (insertions, deletions and substitutions of characters).
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let substitution = diagonal + usize::from(ca != cb);
            diagonal = row[j + 1];
            row[j + 1] = substitution.min(row[j] + 1).min(diagonal + 1);
        }
    }
    row[b.len()]
}

/// An option chosen by name (`--sampler sobol`, `--light-groups per-light`): its values and the names the
/// command line, the C API and scene files spell them with. Library enums implement it instead of depending on a
/// command-line parser; the CLI builds its value parsers from [`Choice::CHOICES`].
pub trait Choice: Copy + PartialEq + Sized + 'static {
    /// Every value with its name, in the order help texts list them.
    const CHOICES: &'static [(&'static str, Self)];

    /// The value named `name`, if any.
    fn from_name(name: &str) -> Option<Self> {
        Self::CHOICES
            .iter()
            .find(|(n, _)| *n == name)
            .map(|&(_, value)| value)
    }

    /// The value's name.
    fn name(self) -> &'static str {
        Self::CHOICES
            .iter()
            .find(|(_, value)| *value == self)
            .map_or("", |(n, _)| n)
    }
}

internal! {
    /// The Markdown table of `keys` that docs/reference.md shows: key, type, default, USD attribute, meaning. Keys of
    /// nested objects follow their parent as `parent.key`.
    #[cfg(test)]
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
    fn unknown_keys_are_found_with_the_closest_known_key() {
        const NESTED: ParamKey = ParamKey {
            name: "noise",
            ty: ParamType::Object(&[N, K]),
            default: ParamDefault::Unset,
            doc: "",
            usd: UsdBinding::Attribute,
        };
        let keys = [N, C, NESTED];
        let v = json!({"n": 1, "cc": 2, "zebra": 3, "noise": {"k": "a", "kk": 1}});
        let found = unknown_json_keys(&v, &keys);
        let shown: Vec<String> = found.iter().map(|k| format!("{k}{}", k.hint())).collect();
        assert_eq!(
            shown,
            [
                "unknown key 'cc' (did you mean 'c'?)",
                "unknown key 'noise.kk' (did you mean 'k'?)",
                "unknown key 'zebra'",
            ]
        );
        let extras = json!({"nimbus_volme": {}, "nimbus_volume": {}, "blender_prop": 1});
        let found = unknown_json_names(&extras, &["nimbus_volume", "nimbus_camera"], "nimbus_");
        assert_eq!(
            found,
            [UnknownKey {
                key: "nimbus_volme".into(),
                closest: Some("nimbus_volume".into())
            }]
        );
        assert!(unknown_json_keys(&json!({"n": 1}), &keys).is_empty());
        assert_eq!(edit_distance("densty_scale", "density_scale"), 1);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(
            closest_name("densty_scale", ["density_scale", "density_grid"]),
            Some("density_scale")
        );
        assert_eq!(closest_name("colour", ["map", "intensity"]), None);
    }

    /// Every option's names are distinct and read back to their values, and the names the CLI and its
    /// documentation have always used are kept (they were clap's kebab-case names of the variants).
    #[test]
    fn choices_round_trip_by_name() {
        fn check<T: Choice + std::fmt::Debug>(expected: &[&str]) {
            let names: Vec<&str> = T::CHOICES.iter().map(|(n, _)| *n).collect();
            assert_eq!(names, expected);
            for &(name, value) in T::CHOICES {
                assert_eq!(T::from_name(name), Some(value));
                assert_eq!(value.name(), name);
            }
            assert_eq!(T::from_name("no-such-name"), None);
        }
        check::<crate::render::Sampler>(&["sobol", "independent"]);
        check::<crate::render::EmitterEdgeSampling>(&["auto", "off"]);
        check::<crate::render::LightGroupMode>(&["scene", "per-light", "off"]);
        check::<crate::light::LightSamplerChoice>(&["auto", "power", "bvh"]);
        check::<crate::output::ExrCompression>(&["zip", "piz", "pxr24", "b44", "rle", "none"]);
        check::<crate::output::HalfFloats>(&["off", "aovs", "all"]);
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
