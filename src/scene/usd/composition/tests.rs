//! The composition check's tests: stages written as text layers, each refused or accepted as Pixar's USD and
//! `openusd` 0.6 compose it.

use super::*;
use openusd::ar;

/// Writes `files` (name, text) to a fresh folder and checks the stage whose root is the first.
fn check_files(tag: &str, files: &[(&str, &str)]) -> Result<(), CompositionError> {
    check_with(tag, files, Limits::default())
}

/// [`check_files`] under `limits`.
fn check_with(tag: &str, files: &[(&str, &str)], limits: Limits) -> Result<(), CompositionError> {
    let root = write_files(tag, files);
    check(root.to_str().unwrap(), &resolver(), &limits)
}

/// Only the pre-caching model's check of the stage `files` make (the walk left out).
fn precache_files(tag: &str, files: &[(&str, &str)]) -> Result<(), CompositionError> {
    let root = write_files(tag, files);
    let resolver = resolver();
    let (layers, _) = Layers::load(&resolver, root.to_str().unwrap());
    precache::Precache::new(&layers).check(Limits::default().usd_prims)
}

/// Writes `files` (name, text) to a fresh folder; returns the path of the first, the root layer.
fn write_files(tag: &str, files: &[(&str, &str)]) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus_composition_{}_{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    for (name, text) in files {
        std::fs::write(dir.join(name), format!("#usda 1.0\n{text}")).unwrap();
    }
    dir.join(files[0].0)
}

/// The resolver the loader checks layers through, with the default limits.
fn resolver() -> CheckingResolver {
    CheckingResolver {
        inner: ar::DefaultResolver::new(),
        limits: Limits::default(),
    }
}

/// Pixar's USD (usd-core 26.11) reports an arc cycle on this stage; `openusd` 0.6 composed it for minutes.
#[test]
fn an_ancestors_arc_back_into_the_run_is_a_cycle() {
    let root = "(\n defaultPrim = \"A\"\n)\ndef \"A\" (references = @./a.usda@</C/C>) {}";
    let asset = "over \"C\" (payload = @./root.usda@) { def \"C\" {} }";
    let err = check_files("ancestor_cycle", &[("root.usda", root), ("a.usda", asset)])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("composition cycle") && err.contains("/C/C is under /C, which payload"),
        "{err}"
    );
}

/// Pixar's USD reports an arc cycle: /A composes /C/D, whose parent's reference maps it onto /A/D, and so on
/// ever deeper (`openusd` 0.6 never met the same site twice and ran for minutes).
#[test]
fn arcs_that_map_a_prim_ever_deeper_are_a_cycle() {
    let root = "def \"A\" (references = </C/D>) {}\ndef \"C\" (references = </A>) { def \"D\" {} }";
    let err = check_files("deeper", &[("root.usda", root)])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("composition cycle") && err.contains("back inside /A"),
        "{err}"
    );
}

/// Ancestors' arcs that map a prim ever deeper, never nested with the prims they started from: in `l1`'s
/// stack (which holds `root`), `/B` specializes `/A/B/D` and `/A` specializes `/B/B/A`, so `/B/A/C` maps to
/// `/A/B/D/A/C`, then `/B/B/A/B/D/A/C`, and so on. `openusd` 0.6 composed this (the fuzz target's
/// `confirm-run-7a6ce936`, reduced) for over 20 s, Pixar's USD for over 30 s; the walk used to stop
/// following such sites silently, and now refuses the first one deeper than its bound.
#[test]
fn ancestors_arcs_that_map_prims_ever_deeper_are_refused() {
    let root = "def \"A\" (specializes = [</B/B/A>, </B/B/C>])\n{\n    over \"C\" (references = \
                @l1.usda@</B/A/C>)\n    {\n        class \"C\" {\n        }\n    }\n}\n";
    let l1 = "(\n    subLayers = [@root.usda@]\n)\nover \"B\" (specializes = </A/B/D>) {\n}\ndef \"A\" {\n}\n";
    let err = check_files("ever_deeper", &[("root.usda", root), ("l1.usda", l1)])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("maps it onto") && err.contains("deeper than twice the deepest"),
        "{err}"
    );
}

/// Class arcs met below references are implied onto the referencing prims (and specializes copied to the
/// root of the index), each walked with its own arcs: the fuzz target's `confirm-run-5051797f` (unreduced),
/// which `openusd` 0.6 composed for over 20 s and Pixar's USD for over 60 s. Only through the implied
/// classes does the walk reach the class arc that the implied-class rule refuses.
#[test]
fn implied_classes_are_walked_with_their_own_arcs() {
    let l0 = "(\n    defaultPrim = \"A\"\n)\ndef Xform \"A\" (prepend specializes = [</B/B/C>, </B/B/B>]\nprepend references = [</C/B>])\n{\n    over Xform \"D\" (instanceable = true\nprepend references = [@./l1.usda@</C/C>, @./l2.usda@])\n    {\n        class Xform \"B\" (variants = { string v = \"x\" }\nprepend variantSets = \"v\")\n        {\n            variantSet \"v\" = {\n                \"x\" (prepend specializes = [</D/D>]) {}\n            }\n        }\n        over Xform \"C\" (prepend references = [@./l1.usda@</C/C>])\n        {\n        }\n    }\n}\n";
    let l1 = "(\n    subLayers = [@./l2.usda@, @./l2.usda@, @./l2.usda@]\n)\ndef Xform \"B\" (prepend inherits = [</A>, </C>]\nprepend references = [</C>])\n{\n}\ndef Xform \"C\" (prepend references = [@./l0.usda@</A>]\nprepend payload = [@./l1.usda@</A/D/C>])\n{\n}\n";
    let files = [("l0.usda", l0), ("l1.usda", l1), ("l2.usda", "")];
    let err = check_files("implied_walk", &files).unwrap_err().to_string();
    assert!(err.contains("a class arc implied onto"), "{err}");
}

/// A class arc below a reference is implied onto the referencing prim: here /A would inherit its own child.
/// Pixar's USD drops the reference (its target has no specs) with an error; `openusd` 0.6 keeps it and
/// composed the stage for minutes, so it is refused.
#[test]
fn a_class_implied_back_into_the_referencing_prim_is_refused() {
    let root = "def \"A\" (references = @./l1.usda@</C/C>) { over \"C\" (references = @./l1.usda@</C/D>) {} }";
    let asset = "over \"C\" (inherits = </A>) {}\ndef \"A\" {}";
    let err = check_files("implied", &[("root.usda", root), ("l1.usda", asset)])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("implied onto /A's layer stack as /A/C, nested with /A"),
        "{err}"
    );
}

/// A class arc on a child of the referenced prim (met below the reference through children, not arcs) is
/// implied onto the referencing layer stack too: here onto /A/A/C, the prim that composes l1's /C/C/C, as
/// an inherit of its own ancestor /A. Pixar's USD (usd-core 26.11) reports an arc cycle ("/A/A/C CANNOT
/// inherit from /A") in 0.03 s; `openusd` 0.6 mapped the prim ever deeper for 11 s (fuzz target
/// `usd_compose`, `final-run-60ad648e` reduced).
#[test]
fn a_class_implied_from_a_child_below_a_reference_onto_its_ancestor_is_refused() {
    let root = "def \"A\" { def \"A\" (references = @./l1.usda@</C/C>) {} }";
    let asset = "def \"C\" { class \"C\" { over \"C\" (inherits = </A>) {} } }";
    let files = [("root.usda", root), ("l1.usda", asset)];
    let err = check_files("implied_child", &files)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("implied onto /A/A's layer stack as /A, nested with /A/A/C"),
        "{err}"
    );
    // The same class arc on a global class outside the composed prim's namespace is no cycle.
    let asset = "def \"C\" { class \"C\" { over \"C\" (inherits = </K>) {} } }\nclass \"K\" {}";
    let files = [("root.usda", root), ("l1.usda", asset)];
    check_files("implied_child_global", &files).unwrap();
}

/// A class arc authored on an ancestor, met below a payload that an ancestor authors, is implied at the level
/// of those ancestors: /A/C composes l1's /C/C, whose parent's payload brings /D/D/B/C, whose ancestor /D's
/// payload brings l0's /A/D/B/C, whose ancestor /A inherits /C; implied through /D's payload onto l1, /D
/// inherits l1's /C, the ancestor of the run's /C/C. Pixar's USD (usd-core 26.11) reports the arc cycle
/// ("l1 </D> CANNOT inherit from l1 </C>") in 0.02 s; `openusd` 0.6 ran past 60 s (the fuzz target's
/// `slow-composition-a867f5a8`, reduced).
#[test]
fn a_class_implied_at_the_level_of_the_ancestors_that_author_the_arcs_is_refused() {
    let root = "def \"A\" (inherits = </C>) { over \"C\" (references = @./l1.usda@</C/C>) {} }";
    let asset = "def \"C\" (payload = [</D/D/B>, @./l0.usda@</A/B/A>]) {}\n\
                 def \"D\" (payload = @./l0.usda@</A>) {}";
    let files = [("l0.usda", root), ("l1.usda", asset)];
    let err = check_files("implied_ancestors", &files)
        .unwrap_err()
        .to_string();
    assert!(
        err.starts_with("/A: inherits </C> is a composition cycle")
            && err.contains("implied onto /D's layer stack as /C, nested with /C/C"),
        "{err}"
    );
}

/// Arcs of ancestors that lead back into the run at the level of the prims that author them: /A/C composes
/// l1's /B/A/C, whose ancestor /B inherits /A, whose specialize of /B/B/C lies inside /B. Pixar's USD
/// (usd-core 26.11) reports the arc cycle ("l1 </B> inherits from l1 </A> which CANNOT refer to l1
/// </B/B/C>"); the sites themselves never nest (/B/A/C, /A/A/C, /B/B/C/A/C, /A/B/C/A/C... ever deeper), and
/// `openusd` 0.6 ran past 60 s (the fuzz target's `final-run-64d6ea8c`, reduced).
#[test]
fn ancestors_arcs_back_into_the_run_at_their_own_level_are_a_cycle() {
    let root =
        "def \"A\" (specializes = </B/B/C>) { over \"C\" (references = @./l1.usda@</B/A/C>) {} }";
    let asset =
        "(\n subLayers = [@./l0.usda@]\n)\nover \"B\" (inherits = </A> payload = </A/A>) {}";
    let files = [("l0.usda", root), ("l1.usda", asset)];
    let err = check_files("ancestor_level", &files)
        .unwrap_err()
        .to_string();
    // Refused as arcs that map prims ever deeper (the first rule met), or as the cycle it is at the level of
    // the prims that author the arcs.
    assert!(
        err.contains("deeper than twice the deepest")
            || (err.contains("composition cycle")
                && err.contains("at the level of the prims that author the arcs")),
        "{err}"
    );
}

/// A model's usual arcs: a reference to an asset whose prim inherits a class and whose child references a
/// part, and an override below the reference that inherits a class of the stage. Pixar's USD composes it
/// without errors.
#[test]
fn ancestral_arcs_of_an_ordinary_asset_are_no_cycle() {
    let root =
        "def \"World\" {\n def \"Chair\" (references = @./chair.usda@</Chair>) {\n  over \"Leg\" \
                (inherits = </World/Looks/Wood>) {}\n }\n class \"Looks\" { class \"Wood\" {} }\n}";
    let chair = "def \"Chair\" (inherits = </_class_Chair>) { def \"Leg\" (references = </Parts/Leg>) {} }\n\
                 class \"_class_Chair\" {}\nover \"Parts\" { def \"Leg\" { def \"Foot\" {} } }";
    check_files("ordinary", &[("root.usda", root), ("chair.usda", chair)]).unwrap();
}

/// Pixar's USD 26.11 refuses both layers ("Duplicate prim", "Duplicate items exist for field"); `openusd`
/// 0.6 kept both copies, and fuzz inputs built on them composed for minutes or overflowed its stack.
#[test]
fn a_prim_or_an_arc_authored_twice_is_refused() {
    let prim = check_files("twice_prim", &[("root.usda", "def \"A\" {}\ndef \"A\" {}")])
        .unwrap_err()
        .to_string();
    assert!(
        prim.ends_with(
            "root.usda defines prim </A> twice in one scope: Pixar's USD refuses such a layer \
                            (\"Duplicate prim\", \"Duplicate items exist for field\")"
        ),
        "{prim}"
    );
    let nested = "def \"B\" { def \"C\" {}\n def \"C\" {} }";
    let err = check_files("twice_nested", &[("root.usda", nested)])
        .unwrap_err()
        .to_string();
    assert!(err.contains("defines prim </B/C> twice"), "{err}");
    let arcs = "def \"A\" (inherits = [</B>, </B>]) {}\nclass \"B\" {}";
    let err = check_files("twice_arc", &[("root.usda", arcs)])
        .unwrap_err()
        .to_string();
    assert!(err.contains("lists </A> inherits </B> twice"), "{err}");
    // The same target through two kinds of arc, or in two prims, is no duplicate.
    let fine = "def \"A\" (inherits = </B> specializes = </B>) {}\ndef \"C\" (inherits = </B>) {}\nclass \"B\" {}";
    check_files("twice_fine", &[("root.usda", fine)]).unwrap();
}

#[test]
fn parents_of_prim_paths() {
    assert_eq!(parent("/A/B/C"), "/A/B");
    assert_eq!(parent("/A"), "/");
    assert_eq!(parent("/"), "/");
}

#[test]
fn a_parents_inherit_around_a_child_or_a_reference_is_no_cycle() {
    // /A/C composes /B/C (the parent's inherit, mapped), not /B: nothing leads back.
    let stage = "def \"A\" (inherits = </B>) { def \"C\" {} }\nclass \"B\" { def \"X\" (references = </A/C>) {} }";
    check_files("parent_ok", &[("root.usda", stage)]).unwrap();
}

/// `openusd` 0.6 maps each pre-cached target back through every arc of the parent's prim index, chains of
/// arcs included: under /B, which inherits /D, /B/D composes /D/D, which inherits /X, so /X maps onto /B/D,
/// and /B's inherit of /D/D/A maps onto /B/D/A. Pre-caching /B/D/A then finds /B/D and /B/D finds /B/D/A,
/// until its stack overflows (the fuzz target's `final-run-63b4c7ce`, reduced). Pixar's USD (usd-core
/// 26.11) composes the stage in 0.02 s with no error; it is refused as openusd's cycle.
#[test]
fn pre_caching_maps_targets_back_through_chains_of_arcs() {
    let stage =
        "def \"D\" {\n over \"B\" (specializes = </B/A>) {}\n def \"D\" (inherits = </X>) {}\n}\n\
                 def \"B\" (inherits = [</D/D/A>, </D>]) {}\n";
    let err = precache_files("chain", &[("root.usda", stage)])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("is a composition cycle for openusd 0.6")
            && err.contains("/B/D/A -> /B/D -> /B/D/A"),
        "{err}"
    );
}

/// `openusd` 0.6 composes the ancestors of each pre-cached target first, pre-caching theirs: /E's target
/// /D/X/Y has none, but its ancestor /D/X takes /D's inherit of /B/A mapped through /D's reference of /B,
/// /D/A, whose own targets are the same (its parent is /D too), /D/A among them, until its stack overflows (the
/// fuzz target's `final-run-c15c398e`, reduced). Pixar's USD (usd-core 26.11) composes the stage in 0.02 s
/// with no error. The walk refuses it too (an inherit mapped onto the prim's own child); the model on its own:
#[test]
fn pre_caching_composes_the_ancestors_of_each_target() {
    let stage = "class \"B\" {}\ndef \"D\" (inherits = </B/A> references = </B>) {}\n\
                 def \"E\" (inherits = </D/X/Y>) {}\n";
    let err = precache_files("ancestors", &[("root.usda", stage)])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("is a composition cycle for openusd 0.6") && err.contains("/D/A -> /D/A"),
        "{err}"
    );
}

/// A class target met through an arc is composed with its target mapped back through that arc too (Pcp's
/// implied classes): /C inherits /A, so /C/D composes /A/D, whose specializes of /A/A is also /C/A, which
/// inherits /A; so /C/D composes /A with /C/D's path, and /A/D's target /A/A, pre-cached for the child /C/D/A,
/// maps onto /C/D/A itself (the fuzz target's `confirm-run2-55db2b7c`, reduced). Pixar's USD (usd-core
/// 26.11) composes the stage with no error in 0.02 s; `openusd` 0.6 overflowed its stack.
#[test]
fn pre_caching_composes_class_targets_mapped_back_through_the_arcs() {
    let stage = "def \"C\" (inherits = </A>) { over \"A\" (inherits = </A>) {} }\n\
                 def \"A\" { def \"D\" (specializes = </A/A>) {} }\n";
    let err = precache_files("implied_site", &[("root.usda", stage)])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("is a composition cycle for openusd 0.6")
            && err.contains("/C/A/D/A -> /C/A/D/A"),
        "{err}"
    );
}

/// A class target is a path of the layer stack that authors it, mapped into the stage through the arcs of
/// the author's ancestors: /D references the root layer's default prim /A, so /D/A's inherit of /A is an
/// inherit of /D, and /A/B's specializes of /D/A/A composes /D/A below /A/B; the target /D/A/A, pre-cached
/// for /A/B/A, maps onto /A/B/A itself (the fuzz target's `confirm-run2-6717a55a`, reduced). Pixar's USD
/// (usd-core 26.11) composes it with no error in 0.03 s; `openusd` 0.6 overflowed its stack.
#[test]
fn pre_caching_maps_class_targets_through_the_authors_ancestors() {
    let stage = "(\n defaultPrim = \"A\"\n)\n\
                 over \"D\" (references = @./root.usda@) { class \"A\" (inherits = </A>) {} }\n\
                 def \"A\" { over \"B\" (specializes = </D/A/A>) {} }\n";
    let err = precache_files("author_ancestors", &[("root.usda", stage)])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("is a composition cycle for openusd 0.6") && err.contains("/A/B/A -> /A/B/A"),
        "{err}"
    );
}

/// The children a prim composes through its sites are pre-cached too (the fuzz target's
/// `confirm-run-33d695f0`, reduced): /D/A composes /C through its payload and /C composes /A through its own,
/// so /D/A/C holds /D/A/C/B, composed from /A/B, which inherits /A/C; mapped back, that target is
/// /D/A/C/B/C, whose own targets hold it again. No authored prim or once-mapped one leads there. Pixar's USD (usd-core 26.11) composes it with no
/// error in 0.04 s; `openusd` 0.6 overflowed its stack after 2.5 s (the stage unreduced: 9 s).
#[test]
fn pre_caching_starts_from_the_children_composed_through_arcs() {
    let stage = "def \"A\" { def \"B\" (inherits = </A/C>) {} }\n\
                 over \"C\" (payload = </A>) {}\n\
                 def \"D\" { over \"A\" (payload = @./root.usda@</C>) { class \"C\" (inherits = </A>) {} } }\n";
    let err = precache_files("composed_children", &[("root.usda", stage)])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("is a composition cycle for openusd 0.6")
            && err.contains("/D/A/C/B/C -> /D/A/C/B/C"),
        "{err}"
    );
}

#[test]
fn pre_caching_follows_stage_paths_across_layer_stacks() {
    // A class inside a referenced asset, and a payload beside an inherit: targets that lead nowhere back.
    let asset = "def \"X\" { def \"Geo\" (inherits = </X/_cls>) {} class \"_cls\" {} }";
    let stage = "def \"A\" (references = @./asset.usda@</X>) {}\n\
                 def \"B\" (inherits = </K> payload = @./asset.usda@</X>) { def \"C\" {} }\nclass \"K\" {}";
    check_files(
        "precache_ok",
        &[("root.usda", stage), ("asset.usda", asset)],
    )
    .unwrap();
    // A target of another layer stack's prim is taken as the stage's path: /Q, which specializes /A/B, whose
    // parent /A holds the reference whose target specializes /Q again.
    // The walk refuses it too, as an implied class (see the test above); the model on its own:
    let files = [
        (
            "root.usda",
            "def \"A\" (references = @./other.usda@</X>) {}\ndef \"Q\" (specializes = </A/B>) {}",
        ),
        ("other.usda", "def \"X\" (specializes = </Q>) {}"),
    ];
    let walk = check_files("precache_cycle", &files)
        .unwrap_err()
        .to_string();
    assert!(
        walk.starts_with("/X: specializes </Q> is a composition cycle"),
        "{walk}"
    );
    assert_eq!(
        precache_files("precache_model", &files).unwrap_err().to_string(),
        "/Q: specializes </A/B> is a composition cycle for openusd 0.6, whose pre-caching of inherit and \
         specialize targets would follow /Q -> /A/B -> /Q without end (a stack overflow)"
    );
}

#[test]
fn class_targets_mapped_onto_their_own_prim_are_refused() {
    for (tag, stage, message) in [
        (
            "nested",
            "def \"A\" (inherits = [</X/Y>, </X>]) {}",
            "/A: inherits </X/Y> lies inside the target of /A's inherits </X>, which maps it onto /A/Y",
        ),
        (
            "reference",
            "def \"A\" (references = </X> specializes = </X/Y>) {}",
            "/A: specializes </X/Y> lies inside the target of /A's references </X>, which maps it onto /A/Y",
        ),
        (
            "ancestor",
            "def \"A\" (inherits = </X>) { def \"B\" (inherits = </X/B>) {} }",
            "/A/B: inherits </X/B> lies inside the target of /A's inherits </X>, which maps it onto /A/B",
        ),
        // A payload of a layer's default prim (here the root's own /X) maps the same way: the fuzz target's
        // `precache-overflow-e3e50b5a`, which overflowed `openusd`'s stack in 0.8 s.
        (
            "default_prim",
            "(\n defaultPrim = \"X\"\n)\ndef \"A\" (specializes = </X/A> payload = @./root.usda@) {}\n\
             class \"X\" {}",
            "/A: specializes </X/A> lies inside the target of /A's payload @./root.usda@ (its default prim \
             </X>), which maps it onto /A/A",
        ),
    ] {
        let err = check_files(tag, &[("root.usda", stage)]).unwrap_err().to_string();
        assert!(err.starts_with(message), "{err}");
    }
    // Mapped anywhere else, or not strictly inside, it composes (and `openusd` composes it).
    for (tag, stage) in [
        (
            "grandchild",
            "def \"A\" (references = </X> inherits = </X/Y/Z>) {}",
        ),
        (
            "sibling",
            "def \"A\" (inherits = </X>) { def \"B\" (inherits = </X/Q>) {} }",
        ),
        ("same", "def \"A\" (references = </X> inherits = </X>) {}"),
    ] {
        check_files(tag, &[("root.usda", stage)]).unwrap();
    }
}

#[test]
fn class_hierarchies_references_and_variants_are_no_cycles() {
    let stage = r#"
class "_class_Char" { def "Geom" {} }
def "Chars" { def "Bob" (inherits = </_class_Char>) { def "Geom" {} } }
def "Looks" {
def "Base" { def "Shader" {} }
def "Red" (specializes = </Looks/Base>) { def "Shader" {} }
}
def "Proto" { def "Leaf" {} }
def "World" (variantSets = "v" references = @./asset.usda@) {
def "A" (references = </Proto>) {}
def "B" (references = </Proto>) {}
variantSet "v" = { "x" (references = </Proto>) {} }
}
"#;
    let asset = "(\n defaultPrim = \"Asset\"\n)\ndef \"Asset\" (inherits = </_class_Char>) { def \"Geom\" {} }\n";
    check_files("valid", &[("root.usda", stage), ("asset.usda", asset)]).unwrap();
}

#[test]
fn prims_are_counted_once_per_arc_that_brings_them_in() {
    // L<i> holds two children that reference L<i-1>: L0, L1, L2 and L3 compose 1, 5, 13 and 29 prims.
    let mut fan = String::from("def \"L0\" {}\n");
    for i in 1..=3 {
        fan.push_str(&format!(
            "def \"L{i}\" {{ def \"a\" (references = </L{p}>) {{}} def \"b\" (references = </L{p}>) {{}} }}\n",
            p = i - 1
        ));
    }
    let limit = |usd_prims| Limits {
        usd_prims,
        ..Limits::default()
    };
    check_with("fan_48", &[("root.usda", &fan)], limit(48)).unwrap();
    assert_eq!(
        check_with("fan_47", &[("root.usda", &fan)], limit(47)).unwrap_err().to_string(),
        "the stage composes 48 prims through its arcs and children (each counted once per arc that brings it \
         in), over the limit of 47 prims (raise it with --max-prims)"
    );
    let err = check_with("fan_20", &[("root.usda", &fan)], limit(20))
        .unwrap_err()
        .to_string();
    assert!(err.starts_with("/L3 composes 29 prims"), "{err}");
}

/// Pixar's USD (usd-core 26.11) reports a sublayer cycle ("Sublayer hierarchy with root layer ... has
/// cycles") on a layer stack whose layer names a layer it is itself a sublayer of; `openusd` 0.6 composed
/// the fuzz target's stages with such stacks for minutes.
#[test]
fn a_sublayer_cycle_is_refused() {
    let files = [
        ("a.usda", "(\n subLayers = [@./b.usda@]\n)\n"),
        ("b.usda", "(\n subLayers = [@./c.usda@, @./a.usda@]\n)\n"),
        ("c.usda", "def \"C\" {}\n"),
    ];
    let err = check_files("sublayer_cycle", &files)
        .unwrap_err()
        .to_string();
    let cycle = "a.usda, a layer on the path of sublayers that leads to it (a sublayer cycle)";
    assert!(
        err.contains("a.usda: its subLayers lead back to a layer on their path: ")
            && err.contains("b.usda names ")
            && err.ends_with(cycle),
        "{err}"
    );
    // Through a reference too: the referenced layer stack of d names d itself.
    let files = [
        ("r.usda", "def \"A\" (references = @./d.usda@</D>) {}\n"),
        ("d.usda", "(\n subLayers = [@./d.usda@]\n)\ndef \"D\" {}\n"),
    ];
    let err = check_files("sublayer_self", &files)
        .unwrap_err()
        .to_string();
    let cycle = "d.usda, a layer on the path of sublayers that leads to it (a sublayer cycle)";
    assert!(
        err.contains("d.usda names ") && err.ends_with(cycle),
        "{err}"
    );
    // A layer named twice is no cycle (Pixar's USD composes it with no error).
    let files = [
        ("t.usda", "(\n subLayers = [@./u.usda@, @./u.usda@]\n)\n"),
        ("u.usda", "def \"U\" {}\n"),
    ];
    check_files("sublayer_twice", &files).unwrap();
}

#[test]
fn layer_stacks_count_every_naming_of_a_sublayer() {
    // a names b twice, b names c twice: 1 + 2 × (1 + 2) = 7 entries.
    let files = [
        ("a.usda", "(\n subLayers = [@./b.usda@, @./b.usda@]\n)\n"),
        ("b.usda", "(\n subLayers = [@./c.usda@, @./c.usda@]\n)\n"),
        ("c.usda", "def \"C\" {}\n"),
    ];
    let limit = |usd_layer_stack| Limits {
        usd_layer_stack,
        ..Limits::default()
    };
    check_with("stack_7", &files, limit(7)).unwrap();
    let err = check_with("stack_6", &files, limit(6))
        .unwrap_err()
        .to_string();
    assert!(
        err.starts_with("the layer stack of ")
            && err.ends_with(
                "a.usda expands to 7 layers (a sublayer named twice counts twice), over the limit of 6 \
                 (raise it with --max-sublayers)"
            ),
        "{err}"
    );
}

#[test]
fn cycles_through_children_layers_and_parents_name_their_first_arc() {
    let err = check_files(
        "child",
        &[("root.usda", "def \"A\" { def \"C\" (inherits = </A>) {} }")],
    );
    assert_eq!(
        err.unwrap_err().to_string(),
        "/A/C: inherits </A> is a composition cycle (/A holds /A/C, /A/C inherits </A>)"
    );
    let err = check_files(
        "layers",
        &[
            ("a.usda", "def \"A\" (references = @./b.usda@</B>) {}"),
            ("b.usda", "def \"B\" (payload = @./a.usda@</A>) {}"),
        ],
    );
    assert_eq!(
        err.unwrap_err().to_string(),
        "/A: references @./b.usda@</B> is a composition cycle (/A references @./b.usda@</B>, \
         /B payload @./a.usda@</A>)"
    );
    let err = check_files(
        "inside",
        &[(
            "root.usda",
            "def \"A\" (references = </B>) {}\nclass \"B\" (specializes = </A/C>) {}",
        )],
    );
    assert_eq!(
        err.unwrap_err().to_string(),
        "/A: references </B> is a composition cycle (/A references </B>, /B specializes </A/C>, back inside /A)"
    );
    let err = check_files(
        "parent",
        &[(
            "root.usda",
            "def \"B\" (inherits = </D/E>) { def \"C\" {} }\nclass \"D\" (inherits = </B/C>) { def \"E\" {} }",
        )],
    );
    assert_eq!(
        err.unwrap_err().to_string(),
        "/D: inherits </B/C> is a composition cycle (/D/E is under /D, which inherits </B/C>, /B/C is under /B, \
         which inherits </D/E>)"
    );
}

/// `fuzz/open` stage `cc20016f`, reduced: `openusd` 0.6 composed it for 19-23 s (Pixar's USD: 0.02 s).
#[test]
fn an_arc_in_a_variant_into_a_variant_prim_that_composes_it_is_refused() {
    let l0 = r#"(
 subLayers = [@./l2.usda@]
)
def "C" (payload = </B>) {}
class "B" {
class "C" (variants = { string v = "x" } variantSets = "v") {
variantSet "v" = { "x" (inherits = </C/B/D>) {} }
}
}
"#;
    let l2 = "def \"C\" (variants = { string v = \"x\" } variantSets = \"v\") {\nvariantSet \"v\" = { \"x\" \
              (specializes = </A>) {} }\n}\n";
    let err = check_files("variant_recursion", &[("l0.usda", l0), ("l2.usda", l2)])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("/B/C: inherits </C/B/D>")
            && err.contains("inside /C, which has a variant set"),
        "{err}"
    );
    // The same arcs with the inherit outside the variant compose at once in `openusd` 0.6 (and load as before);
    // so do a target outside the prim the stage composes `/B/C` through, and a variant-less `/C`.
    let outside = l0
        .replace(
            "(variants = { string v = \"x\" } variantSets = \"v\")",
            "(inherits = </C/B/D>)",
        )
        .replace("(inherits = </C/B/D>) {}", "() {}");
    check_files(
        "variant_recursion_outside",
        &[("l0.usda", &outside), ("l2.usda", l2)],
    )
    .unwrap();
    let elsewhere = l0.replace("</C/B/D>", "</D/B/D>");
    check_files(
        "variant_recursion_elsewhere",
        &[("l0.usda", &elsewhere), ("l2.usda", l2)],
    )
    .unwrap();
    let plain = "def \"C\" (specializes = </A>) {}\n";
    check_files(
        "variant_recursion_plain",
        &[("l0.usda", l0), ("l2.usda", plain)],
    )
    .unwrap();
}

/// The growth behind `cc20016f`, measured on variations (`openusd` 0.6 recursed through the variant to its depth
/// limit of 100 nested indices, for 0.2 s to past 10 s each): the target anywhere inside the prim that bears the
/// name, and that prim and the arc's parent anywhere in the namespace, through any arc.
#[test]
fn arcs_in_variants_into_a_variant_prim_of_their_name_are_refused_at_any_depth() {
    for (name, holder, arc, parent, target) in [
        ("deep_target", "/C", "payload", "/B", "/C/X/Y/Z/W"),
        ("renamed", "/E", "references", "/B", "/E/X"),
        ("deeper_parent", "/C", "inherits", "/B/E", "/C/X"),
        ("deeper_holder", "/Z/E", "specializes", "/B", "/Z/E/X"),
    ] {
        let own = holder.rsplit('/').next().unwrap();
        let variant = "variants = { string v = \"x\" } variantSets = \"v\"";
        let mut stage = String::new();
        let mut close = String::new();
        for part in holder
            .split('/')
            .skip(1)
            .collect::<Vec<_>>()
            .split_last()
            .unwrap()
            .1
        {
            stage += &format!("def \"{part}\" {{\n");
            close += "}\n";
        }
        stage += &format!(
            "def \"{own}\" ({arc} = <{parent}> {variant}) {{ variantSet \"v\" = {{ \"x\" () {{}} }} }}\n{close}"
        );
        let mut classes = String::new();
        for part in parent.split('/').skip(1) {
            classes += &format!("class \"{part}\" {{\n");
        }
        classes += &format!(
            "class \"{own}\" ({variant}) {{ variantSet \"v\" = {{ \"x\" (inherits = <{target}>) {{}} }} }}\n"
        );
        classes += &"}\n".repeat(parent.split('/').count() - 1);
        let err = check_files(
            &format!("variant_recursion_{name}"),
            &[("root.usda", &(stage + &classes))],
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.contains(&format!("inherits <{target}>"))
                && err.contains(&format!("inside {holder}, which has")),
            "{name}: {err}"
        );
    }
    // A target inside the prim's own image (`/R/Q`, where `/R`'s reference composes `/B/Q`) recursed the same
    // way in `openusd` 0.6 (1.6 s); it is an arc cycle, refused by the walk's cycle rule.
    let image = r#"def "R" (references = </B> variants = { string v = "x" } variantSets = "v") { variantSet "v" = { "x" () {} } }
class "B" {
class "Q" (variants = { string v = "x" } variantSets = "v") { variantSet "v" = { "x" (inherits = </R/Q/X>) {} } }
}
"#;
    let err = check_files("variant_recursion_image", &[("root.usda", image)])
        .unwrap_err()
        .to_string();
    assert!(err.contains("composition cycle"), "{err}");
}
