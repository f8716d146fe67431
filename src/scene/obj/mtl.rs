//! The MTL material library parser: every statement checked, with its line, before any value is used.
//!
//! Colours (`Ka`, `Kd`, `Ks`, `Ke`, `Tf`, `Kt`) are exactly three finite numbers (the `spectral` and `xyz` forms
//! are refused); numeric keys (`Ns`, `Ni`, `d`, `Tr`, ...) one finite number; `illum` an integer 0 to 255.
//! Texture statements (`map_Kd`, `map_Ke`, `map_d`, `map_Bump`/`bump`, `norm`, and the ones Nimbus does not
//! read) are `key [options] file`, the file name being the rest of the line (it may hold spaces). The options of
//! the MTL specification (Wavefront, "MTL material format", Lightwave-based revision 4.2, "Options for texture map
//! statements") are parsed with their arguments: `-o`/`-s`/`-t u [v [w]]`, `-bm`, `-boost`, `-texres` one number,
//! `-mm base gain`, `-blendu`/`-blendv`/`-cc`/`-clamp on|off`, `-imfchan r|g|b|m|l|z`, `-type name`. An unknown
//! option is an error naming it; the ones Nimbus does not honour are listed in one warning per library.
//! Keys are case-sensitive except the texture keys (`map_kd` and `MAP_KD` are `map_Kd`), which exporters spell
//! in every case.

use super::{bad, numbers, LineError, QUOTE_CHARS};
use crate::limits::one_line;
use crate::math::{Rgb, Vec2};
use crate::scene::SceneErrorKind;

/// What a texture statement feeds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum MapKind {
    /// `map_Kd`: the base colour (sRGB), multiplied with `Kd`.
    Diffuse,
    /// `map_Ke`: the emission (sRGB), multiplied with `Ke`.
    Emission,
    /// `map_d`: coverage (a cut-out).
    Dissolve,
    /// `map_Bump` / `bump`: a height map.
    Bump,
    /// `norm`: a tangent-space normal map.
    Normal,
}

/// One texture statement.
#[derive(Clone, Debug)]
pub(super) struct TextureMap {
    /// The statement's key as written (for messages).
    pub key: String,
    /// What it feeds; `None` for a key Nimbus does not read (`map_Ks`, `map_Ns`, `refl`, ...).
    pub kind: Option<MapKind>,
    /// The file name as written.
    pub file: String,
    /// Its line in the MTL file.
    pub line: usize,
    /// `-bm`: the bump multiplier (1 by default).
    pub bump_multiplier: f32,
    /// `-o u v`: the texture-coordinate offset.
    pub offset: Vec2,
    /// `-s u v`: the texture-coordinate scale.
    pub scale: Vec2,
    /// `-clamp on`: clamp texture coordinates to \[0, 1\] instead of repeating.
    pub clamp: bool,
    /// `-imfchan`: the channel a scalar texture is read from (`r`, `g`, `b`, `m` matte = alpha, `l` luminance).
    pub channel: Option<char>,
}

/// One `newmtl` block.
#[derive(Clone, Debug, Default)]
pub(super) struct MtlMaterial {
    /// The name after `newmtl`.
    pub name: String,
    /// `Kd`.
    pub diffuse: Option<Rgb>,
    /// `Ks`.
    pub specular: Option<Rgb>,
    /// `Ke`.
    pub emissive: Option<Rgb>,
    /// `Ns`.
    pub shininess: Option<f32>,
    /// `Ni`.
    pub ior: Option<f32>,
    /// `d`.
    pub dissolve: Option<f32>,
    /// `Tr` (1 − d; `d` wins when both are given).
    pub transparency: Option<f32>,
    /// `illum`.
    pub illum: Option<u8>,
    /// The texture statements, in order.
    pub maps: Vec<TextureMap>,
}

impl MtlMaterial {
    /// The coverage: `d`, else 1 − `Tr`, else 1.
    pub fn coverage(&self) -> f32 {
        self.dissolve
            .or(self.transparency.map(|t| 1.0 - t))
            .unwrap_or(1.0)
            .clamp(0.0, 1.0)
    }

    /// The last statement feeding `kind`, if any.
    pub fn map(&self, kind: MapKind) -> Option<&TextureMap> {
        self.maps.iter().rev().find(|m| m.kind == Some(kind))
    }
}

/// A parsed library: its materials and the texture options it uses that Nimbus ignores.
#[derive(Debug, Default)]
pub(super) struct Library {
    /// The materials, in file order.
    pub materials: Vec<MtlMaterial>,
    /// Texture options given but not honoured (`-blendu`, `-mm`, ...), each once.
    pub ignored_options: Vec<String>,
    /// Texture keys given but not read (`map_Ks`, `refl`, ...), each once.
    pub unread_maps: Vec<String>,
}

const COLORS: [&str; 6] = ["Ka", "Kd", "Ks", "Ke", "Tf", "Kt"];
const SCALARS: [&str; 12] = [
    "Ns",
    "Ni",
    "d",
    "Tr",
    "sharpness",
    "Pr",
    "Pm",
    "Ps",
    "Pc",
    "Pcr",
    "aniso",
    "anisor",
];
/// Texture keys that take `key [options] file` but that Nimbus does not read.
const UNREAD_MAPS: [&str; 4] = ["refl", "disp", "decal", "map_aat"];

/// The kind of a texture key (case-insensitive), `Some(None)` for one Nimbus does not read, `None` when `key`
/// is no texture key.
fn map_kind(key: &str) -> Option<Option<MapKind>> {
    let lower = key.to_ascii_lowercase();
    Some(match lower.as_str() {
        "map_kd" => Some(MapKind::Diffuse),
        "map_ke" => Some(MapKind::Emission),
        "map_d" => Some(MapKind::Dissolve),
        "map_bump" | "bump" => Some(MapKind::Bump),
        "norm" | "map_norm" => Some(MapKind::Normal),
        k if k.starts_with("map_") || UNREAD_MAPS.contains(&k) => None,
        _ => return None,
    })
}

/// Parses a whole MTL library.
pub(super) fn parse(text: &str) -> Result<Library, LineError> {
    let mut library = Library::default();
    let mut current: Option<MtlMaterial> = None;
    for (i, line) in text.lines().enumerate() {
        let n = i + 1;
        let trimmed = line.trim();
        let mut words = trimmed.split_whitespace();
        let Some(key) = words.next() else { continue };
        if key.starts_with('#') {
            continue;
        }
        let args: Vec<&str> = words.collect();
        if key == "newmtl" {
            let name = trimmed["newmtl".len()..].trim();
            if name.is_empty() {
                return Err(bad(n, "newmtl: no name".into()));
            }
            library.materials.extend(current.take());
            current = Some(MtlMaterial {
                name: name.to_owned(),
                ..Default::default()
            });
            continue;
        }
        // Statements before the first `newmtl` belong to no material: checked, then dropped.
        let mut scratch = MtlMaterial::default();
        let m = current.as_mut().unwrap_or(&mut scratch);
        if COLORS.contains(&key) {
            let c = color(n, key, &args)?;
            match key {
                "Kd" => m.diffuse = Some(c),
                "Ks" => m.specular = Some(c),
                "Ke" => m.emissive = Some(c),
                _ => {}
            }
        } else if SCALARS.contains(&key) {
            let x = numbers(n, key, &args)?;
            if x.len() != 1 {
                return Err(bad(
                    n,
                    format!("{key}: expected 1 number, found {}", x.len()),
                ));
            }
            match key {
                "Ns" => m.shininess = Some(x[0]),
                "Ni" => m.ior = Some(x[0]),
                "d" => m.dissolve = Some(x[0]),
                "Tr" => m.transparency = Some(x[0]),
                _ => {}
            }
        } else if key == "illum" {
            match args[..] {
                [a] => match a.parse::<u8>() {
                    Ok(v) => m.illum = Some(v),
                    Err(_) => return Err(bad(n, "illum: expected one integer 0 to 255".into())),
                },
                _ => return Err(bad(n, "illum: expected one integer 0 to 255".into())),
            }
        } else if let Some(kind) = map_kind(key) {
            let rest = trimmed[key.len()..].trim_start();
            let map = texture_statement(n, key, kind, rest, &mut library.ignored_options)?;
            if kind.is_none() && !library.unread_maps.contains(&map.key) {
                library.unread_maps.push(map.key.clone());
            }
            m.maps.push(map);
        }
    }
    library.materials.extend(current);
    Ok(library)
}

/// Exactly three finite numbers `r g b`.
fn color(n: usize, key: &str, args: &[&str]) -> Result<Rgb, LineError> {
    if let Some(form) = args.first().filter(|a| **a == "spectral" || **a == "xyz") {
        return Err((
            SceneErrorKind::Unsupported,
            n,
            format!("{key}: the '{form}' colour form (only r g b is read)"),
        ));
    }
    let x = numbers(n, key, args)?;
    if x.len() != 3 {
        return Err(bad(
            n,
            format!("{key}: expected 3 numbers (r g b), found {}", x.len()),
        ));
    }
    Ok(Rgb::new(x[0], x[1], x[2]))
}

/// The first whitespace-separated word of `text` and what follows it (its leading space trimmed).
fn split_word(text: &str) -> Option<(&str, &str)> {
    let text = text.trim_start();
    if text.is_empty() {
        return None;
    }
    let end = text.find(char::is_whitespace).unwrap_or(text.len());
    Some((&text[..end], text[end..].trim_start()))
}

/// Parses `[options] file` after a texture key.
fn texture_statement(
    n: usize,
    key: &str,
    kind: Option<MapKind>,
    mut rest: &str,
    ignored: &mut Vec<String>,
) -> Result<TextureMap, LineError> {
    let mut map = TextureMap {
        key: key.to_owned(),
        kind,
        file: String::new(),
        line: n,
        bump_multiplier: 1.0,
        offset: Vec2::ZERO,
        scale: Vec2::ONE,
        clamp: false,
        channel: None,
    };
    while let Some((word, after)) = split_word(rest) {
        if !word.starts_with('-') || word.len() < 2 {
            break;
        }
        let option = word.to_owned();
        let mut args = OptionWords {
            line: n,
            what: format!("{key} {option}"),
            rest: after,
        };
        let honoured = texture_option(&mut map, key, &option, &mut args)?;
        rest = args.rest;
        if !honoured && !ignored.contains(&option) {
            ignored.push(option);
        }
    }
    let file = rest.trim();
    if file.is_empty() {
        return Err(bad(n, format!("{key}: no file name")));
    }
    map.file = file.to_owned();
    Ok(map)
}

/// The words after a texture option on line `line`, taken as the option needs them; `what` names the option in
/// errors.
struct OptionWords<'a> {
    line: usize,
    what: String,
    rest: &'a str,
}

impl OptionWords<'_> {
    /// The next word, which the option needs.
    fn word(&mut self) -> Result<String, LineError> {
        let (word, after) = split_word(self.rest)
            .ok_or_else(|| bad(self.line, format!("{}: a value is missing", self.what)))?;
        self.rest = after;
        Ok(word.to_owned())
    }

    /// `word` read as a number.
    fn parse(&self, word: &str) -> Result<f32, LineError> {
        Ok(numbers(self.line, &self.what, &[word])?[0])
    }

    /// The next word, a number.
    fn number(&mut self) -> Result<f32, LineError> {
        let word = self.word()?;
        self.parse(&word)
    }

    /// The next word, `on` or `off`.
    fn on_off(&mut self) -> Result<bool, LineError> {
        match self.word()?.as_str() {
            "on" => Ok(true),
            "off" => Ok(false),
            other => Err(bad(
                self.line,
                format!(
                    "{}: expected on or off, found '{}'",
                    self.what,
                    one_line(other, QUOTE_CHARS)
                ),
            )),
        }
    }
}

/// The channel an `-imfchan` option names: r, g, b, m, l or z.
fn channel(args: &mut OptionWords) -> Result<char, LineError> {
    let a = args.word()?;
    match a.as_str() {
        "r" | "g" | "b" | "m" | "l" | "z" => Ok(a.chars().next().unwrap_or('l')),
        _ => Err(bad(
            args.line,
            format!(
                "{}: expected r, g, b, m, l or z, found '{}'",
                args.what,
                one_line(&a, QUOTE_CHARS)
            ),
        )),
    }
}

/// The values of an `-o`, `-s` or `-t` option: one to three numbers (u, then optionally v and w), as u and v
/// (v `default` when absent).
fn uv_option(args: &mut OptionWords, default: f32) -> Result<Vec2, LineError> {
    let mut values = vec![args.number()?];
    while values.len() < 3 {
        match split_word(args.rest) {
            Some((w, after)) if w.parse::<f32>().is_ok() => {
                values.push(args.parse(w)?);
                args.rest = after;
            }
            _ => break,
        }
    }
    Ok(Vec2::new(
        values[0],
        values.get(1).copied().unwrap_or(default),
    ))
}

/// Reads texture option `option` of statement `key` (its values from `args`) into `map`; returns whether Nimbus
/// honours it (`-bm`, `-clamp`, `-imfchan`, `-o`, `-s`) or only checks and ignores it (`-blendu`, `-blendv`,
/// `-cc`, `-boost`, `-texres`, `-mm`, `-type`, `-t`). An unknown option is an error.
fn texture_option(
    map: &mut TextureMap,
    key: &str,
    option: &str,
    args: &mut OptionWords,
) -> Result<bool, LineError> {
    Ok(match option {
        "-bm" => {
            map.bump_multiplier = args.number()?;
            true
        }
        "-clamp" => {
            map.clamp = args.on_off()?;
            true
        }
        "-blendu" | "-blendv" | "-cc" => {
            args.on_off()?;
            false
        }
        "-boost" | "-texres" => {
            args.number()?;
            false
        }
        "-mm" => {
            args.number()?;
            args.number()?;
            false
        }
        "-imfchan" => {
            map.channel = Some(channel(args)?);
            true
        }
        "-type" => {
            args.word()?;
            false
        }
        "-o" | "-s" | "-t" => {
            let default = if option == "-s" { 1.0 } else { 0.0 };
            let uv = uv_option(args, default)?;
            match option {
                "-o" => map.offset = uv,
                "-s" => map.scale = uv,
                _ => {}
            }
            option != "-t"
        }
        _ => {
            return Err(bad(
                args.line,
                format!(
                    "{key}: unknown texture option '{}'",
                    one_line(option, QUOTE_CHARS)
                ),
            ))
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_then_a_file_name_with_spaces() {
        let lib = parse("newmtl a\nmap_Kd -o 0.5 -s 2 3 -bm 0.5 -clamp on my tex.png\n").unwrap();
        let m = &lib.materials[0].maps[0];
        assert_eq!(m.file, "my tex.png");
        assert_eq!(m.offset, Vec2::new(0.5, 0.0));
        assert_eq!(m.scale, Vec2::new(2.0, 3.0));
        assert_eq!((m.bump_multiplier, m.clamp), (0.5, true));
        assert!(lib.ignored_options.is_empty());
    }

    #[test]
    fn texture_keys_are_case_insensitive_and_unread_ones_listed() {
        let lib = parse("newmtl a\nMAP_KD a.png\nmap_Ks b.png\nrefl -type sphere c.png\n").unwrap();
        let m = &lib.materials[0];
        assert_eq!(m.map(MapKind::Diffuse).unwrap().file, "a.png");
        assert_eq!(lib.unread_maps, ["map_Ks", "refl"]);
        assert_eq!(lib.ignored_options, ["-type"]);
    }
}
