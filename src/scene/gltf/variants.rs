//! `KHR_materials_variants`: the root extension's `variants[].name`, the variant chosen by
//! [`crate::scene::LoadOptions::variant`], and each primitive's `mappings[]` (`material`, `variants`).

use super::{Loader, QUOTE};
use crate::limits::one_line;
use crate::scene::MalformedPart;
use crate::scene::{SceneError, SceneErrorKind};
use std::collections::HashMap;

impl Loader<'_> {
    /// The material index `KHR_materials_variants` gives the chosen variant on a primitive, if the primitive
    /// maps it. Every mapping is checked, whichever variant is chosen: `material` must name a material, and
    /// each of `variants` a variant of the file, at most once on the primitive (the extension's rule).
    pub(super) fn variant_material(
        &self,
        primitive: &gltf::Primitive,
        what: &str,
    ) -> Result<Option<usize>, SceneError> {
        let Some(ext) = primitive.extension_value("KHR_materials_variants") else {
            return Ok(None);
        };
        let at = format!("{what}: extensions.KHR_materials_variants");
        let mappings = ext
            .get("mappings")
            .and_then(|m| m.as_array())
            .ok_or_else(|| {
                self.malformed(
                    MalformedPart::Material,
                    format!("{at}.mappings must be an array"),
                )
            })?;
        let materials = self.document.materials().len();
        // The mapping that named each variant met so far: the work follows the primitive's own mappings, not
        // the file's count of variants.
        let mut mapped_at: HashMap<usize, usize> = HashMap::new();
        let mut chosen = None;
        for (i, mapping) in mappings.iter().enumerate() {
            let material = mapping
                .get("material")
                .and_then(|m| m.as_u64())
                .filter(|&m| m < materials as u64)
                .ok_or_else(|| {
                    self.error(SceneErrorKind::InvalidReference(format!(
                        "{at}.mappings[{i}].material must be the index of a material ({materials} materials)"
                    )))
                })? as usize;
            let variants = mapping
                .get("variants")
                .and_then(|v| v.as_array())
                .ok_or_else(|| {
                    self.malformed(
                        MalformedPart::Material,
                        format!("{at}.mappings[{i}].variants must be an array"),
                    )
                })?;
            for v in variants {
                let index = v
                    .as_u64()
                    .filter(|&v| v < self.variant_count as u64)
                    .ok_or_else(|| {
                        self.error(SceneErrorKind::InvalidReference(format!(
                            "{at}.mappings[{i}].variants: {} is not the index of a variant ({} variants)",
                            one_line(&v.to_string(), QUOTE),
                            self.variant_count
                        )))
                    })? as usize;
                if let Some(first) = mapped_at.insert(index, i) {
                    return Err(self.malformed(
                        MalformedPart::Material,
                        format!(
                        "{at}: variant {index} is mapped by mappings[{first}] and mappings[{i}]"
                    ),
                    ));
                }
                if self.variant == Some(index) {
                    chosen = Some(material);
                }
            }
        }
        Ok(chosen)
    }
}

/// A malformed `KHR_materials_variants` root extension ([`variant_names`]).
#[derive(Debug, thiserror::Error)]
pub(super) enum VariantsError {
    /// `variants` is missing or not an array.
    #[error("extensions.KHR_materials_variants.variants must be an array")]
    NotAnArray,
    /// The entry at this index has no string `name`.
    #[error("extensions.KHR_materials_variants.variants[{0}].name must be a string")]
    UnnamedVariant(usize),
}

/// The names of the file's `KHR_materials_variants` variants (the root extension's `variants[i].name`), in
/// order; none without the extension. An error names a malformed entry.
pub(super) fn variant_names(document: &gltf::Document) -> Result<Vec<String>, VariantsError> {
    let Some(ext) = document.extension_value("KHR_materials_variants") else {
        return Ok(Vec::new());
    };
    let variants = ext
        .get("variants")
        .and_then(|v| v.as_array())
        .ok_or(VariantsError::NotAnArray)?;
    variants
        .iter()
        .enumerate()
        .map(|(i, v)| {
            v.get("name")
                .and_then(|n| n.as_str())
                .map(str::to_owned)
                .ok_or(VariantsError::UnnamedVariant(i))
        })
        .collect()
}

/// The index of the variant named `wanted` among `variants`: `None` when none is wanted; an error listing the
/// variants when the file has no variant of that name, or several.
pub(super) fn choose_variant(
    variants: &[String],
    wanted: Option<&str>,
) -> Result<Option<usize>, SceneErrorKind> {
    let Some(wanted) = wanted else {
        return Ok(None);
    };
    let list = || {
        let names: Vec<String> = variants.iter().map(|n| one_line(n, QUOTE)).collect();
        one_line(&names.join(", "), 8 * QUOTE)
    };
    let matches: Vec<usize> = (0..variants.len())
        .filter(|&i| variants[i] == wanted)
        .collect();
    match matches[..] {
        [i] => Ok(Some(i)),
        [] if variants.is_empty() => Err(SceneErrorKind::InvalidReference(format!(
            "material variant '{}': the file has no material variants (KHR_materials_variants)",
            one_line(wanted, QUOTE)
        ))),
        [] => Err(SceneErrorKind::InvalidReference(format!(
            "the file has no material variant '{}'; its variants are: {}",
            one_line(wanted, QUOTE),
            list()
        ))),
        _ => Err(SceneErrorKind::malformed(
            MalformedPart::Material,
            format!(
                "{} material variants are named '{}' (variants: {})",
                matches.len(),
                one_line(wanted, QUOTE),
                list()
            ),
        )),
    }
}
