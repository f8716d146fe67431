//! The library's public API, listed item by item and compared with the committed list `tests/public_api.txt`.
//!
//! The list comes from rustdoc's JSON output of the library built without default features (what an embedder
//! sees): every module, type, field, variant, function and method (with its signature), constant, trait and trait
//! impl reachable from the crate root, under each path that reaches it. Adding, removing or changing a public item
//! without updating the list fails this test; after a deliberate change, rewrite the list with
//!
//! ```text
//! NIMBUS_BLESS_PUBLIC_API=1 cargo test --test public_api
//! ```
//!
//! and commit it with the change (docs/api.md says what belongs in the API).
//!
//! rustdoc's JSON is unstable, so the test runs one pinned nightly ([`TOOLCHAIN`]; a toolchain named `nightly`
//! is taken too when it is that same compiler). Without it the test is skipped with the reason printed, unless
//! `NIMBUS_REQUIRE_NIGHTLY` is set (CI sets it and installs the toolchain), where it fails.

use serde_json::Value;
use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The pinned nightly whose rustdoc writes the JSON this test reads.
const TOOLCHAIN: &str = "nightly-2026-05-20";
/// That nightly's `rustc --version` commit and date, to recognise it under another toolchain name.
const RUSTC_COMMIT: &str = "e50aa6fba 2026-05-19";
/// The rustdoc JSON format of that nightly: the walk below reads this format and no other.
const FORMAT_VERSION: u64 = 57;

#[test]
fn public_api_matches_the_committed_list() {
    let Some(toolchain) = pinned_toolchain() else {
        let reason = format!(
            "the public API test needs the pinned nightly `{TOOLCHAIN}` (rustc {RUSTC_COMMIT}): install it with \
             `rustup toolchain install {TOOLCHAIN} --profile minimal`"
        );
        if std::env::var_os("NIMBUS_REQUIRE_NIGHTLY").is_some() {
            panic!("{reason} (NIMBUS_REQUIRE_NIGHTLY is set)");
        }
        eprintln!("skipped: {reason}");
        return;
    };
    let json = rustdoc_json(&toolchain);
    let listed = list_public_items(&json);
    let text: String = listed.iter().map(|line| format!("{line}\n")).collect();
    let committed_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/public_api.txt");
    if std::env::var_os("NIMBUS_BLESS_PUBLIC_API").is_some() {
        std::fs::write(&committed_path, &text).expect("write tests/public_api.txt");
        eprintln!(
            "wrote {} public items to {}",
            listed.len(),
            committed_path.display()
        );
        return;
    }
    let committed = std::fs::read_to_string(&committed_path).unwrap_or_default();
    let committed: BTreeSet<String> = committed.lines().map(str::to_owned).collect();
    let added: Vec<_> = listed.difference(&committed).collect();
    let removed: Vec<_> = committed.difference(&listed).collect();
    if !added.is_empty() || !removed.is_empty() {
        let mut message = String::from("the public API differs from tests/public_api.txt:\n");
        for line in &added {
            message += &format!("  + {line}\n");
        }
        for line in &removed {
            message += &format!("  - {line}\n");
        }
        message += "If the change is deliberate (docs/api.md says what belongs in the API), update the list with\n  \
                    NIMBUS_BLESS_PUBLIC_API=1 cargo test --test public_api\nand commit tests/public_api.txt.";
        panic!("{message}");
    }
    eprintln!("{} public items, as listed", listed.len());
}

/// The pinned nightly, under its own name or as `nightly` when that is the same compiler.
fn pinned_toolchain() -> Option<String> {
    [TOOLCHAIN, "nightly"].into_iter().find_map(|name| {
        let out = Command::new("rustup")
            .args(["run", name, "rustc", "--version"])
            .output()
            .ok()?;
        let version = String::from_utf8_lossy(&out.stdout);
        (out.status.success() && version.contains(RUSTC_COMMIT)).then(|| name.to_owned())
    })
}

/// rustdoc's JSON for the library without default features, built in a target directory of its own.
fn rustdoc_json(toolchain: &str) -> Value {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR")).join("Cargo.toml");
    let target: PathBuf = Path::new(env!("CARGO_TARGET_TMPDIR")).join("public-api");
    let mut command = Command::new("rustup");
    command.args([
        "run", toolchain, "cargo", "rustdoc", "--quiet", "--locked", "-p", "nimbus", "--lib",
    ]);
    command
        .args(["--no-default-features", "--manifest-path"])
        .arg(&manifest);
    command.arg("--target-dir").arg(&target);
    command.args([
        "--",
        "-Z",
        "unstable-options",
        "--output-format",
        "json",
        "-A",
        "warnings",
    ]);
    // The outer `cargo test` runs on another toolchain: none of its settings may leak into this build.
    for variable in [
        "RUSTUP_TOOLCHAIN",
        "RUSTC",
        "RUSTDOC",
        "RUSTC_WRAPPER",
        "RUSTC_WORKSPACE_WRAPPER",
        "RUSTFLAGS",
        "RUSTDOCFLAGS",
        "CARGO_ENCODED_RUSTFLAGS",
        "CARGO_ENCODED_RUSTDOCFLAGS",
        "CARGO_TARGET_DIR",
        "CARGO_BUILD_TARGET_DIR",
        "CARGO",
    ] {
        command.env_remove(variable);
    }
    let status = command.status().expect("run cargo rustdoc");
    assert!(
        status.success(),
        "cargo +{toolchain} rustdoc --output-format json failed: {status}"
    );
    let path = target.join("doc/nimbus.json");
    let text =
        std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("read {}: {e}", path.display()));
    let json: Value = serde_json::from_str(&text).expect("rustdoc JSON parses");
    assert_eq!(
        json["format_version"].as_u64(),
        Some(FORMAT_VERSION),
        "rustdoc JSON format changed: this test reads format {FORMAT_VERSION} (toolchain {TOOLCHAIN})"
    );
    json
}

/// One line per public item: its kind, its path from the crate root and, for functions, fields and constants,
/// its type.
fn list_public_items(json: &Value) -> BTreeSet<String> {
    let index: HashMap<String, &Value> = json["index"]
        .as_object()
        .expect("index")
        .iter()
        .map(|(id, item)| (id.clone(), item))
        .collect();
    let mut walk = Walk {
        index,
        out: BTreeSet::new(),
        modules: Vec::new(),
    };
    let root = id_key(&json["root"]);
    walk.item(&root, "nimbus");
    walk.out
}

/// An id as the index's keys spell it.
fn id_key(id: &Value) -> String {
    match id {
        Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

struct Walk<'a> {
    index: HashMap<String, &'a Value>,
    out: BTreeSet<String>,
    /// The modules on the current walk, so that a re-export of an enclosing module ends.
    modules: Vec<String>,
}

impl Walk<'_> {
    /// Lists the item `id` under `path`, and what it holds.
    fn item(&mut self, id: &str, path: &str) {
        let Some(item) = self.index.get(id).copied() else {
            return;
        };
        let (kind, inner) = item["inner"]
            .as_object()
            .and_then(|o| o.iter().next())
            .expect("item kind");
        match kind.as_str() {
            "module" => {
                if self.modules.iter().any(|m| m == id) {
                    return;
                }
                self.out.insert(format!("mod {path}"));
                self.modules.push(id.to_owned());
                self.children(inner, path);
                self.modules.pop();
            }
            "use" => {
                let target = inner.get("id").filter(|t| !t.is_null()).map(id_key);
                let glob = inner["is_glob"].as_bool().unwrap_or(false);
                match target.filter(|t| self.index.contains_key(t)) {
                    Some(target) if glob => {
                        if !self.modules.contains(&target) {
                            self.modules.push(target.clone());
                            let module = self.index[&target]["inner"]["module"].clone();
                            self.children(&module, path);
                            self.modules.pop();
                        }
                    }
                    Some(target) => {
                        let name = inner["name"].as_str().unwrap_or("_");
                        self.item(&target, &format!("{path}::{name}"));
                    }
                    None => {
                        let name = inner["name"].as_str().unwrap_or("*");
                        let source = inner["source"].as_str().unwrap_or("?");
                        self.out.insert(format!("use {path}::{name} = {source}"));
                    }
                }
            }
            "struct" | "union" => {
                let generics = generics(&inner["generics"]);
                self.out.insert(format!("{kind} {path}{generics}"));
                let fields = &inner["kind"];
                if let Some(plain) = fields.get("plain") {
                    self.fields(&plain["fields"], path);
                } else if let Some(tuple) = fields.get("tuple") {
                    self.fields(tuple, path);
                } else if fields.get("fields").is_some() {
                    self.fields(&fields["fields"], path);
                }
                self.impls(&inner["impls"], path);
            }
            "enum" => {
                self.out
                    .insert(format!("enum {path}{}", generics(&inner["generics"])));
                for variant in inner["variants"].as_array().into_iter().flatten() {
                    let variant = id_key(variant);
                    let Some(v) = self.index.get(&variant).copied() else {
                        continue;
                    };
                    let name = v["name"].as_str().unwrap_or("_");
                    let vpath = format!("{path}::{name}");
                    let vkind = &v["inner"]["variant"]["kind"];
                    match vkind {
                        Value::Object(o) if o.contains_key("tuple") => {
                            let types: Vec<String> = o["tuple"]
                                .as_array()
                                .into_iter()
                                .flatten()
                                .map(|f| match self.index.get(&id_key(f)) {
                                    Some(f) => ty(&f["inner"]["struct_field"]),
                                    None => "_".into(),
                                })
                                .collect();
                            self.out
                                .insert(format!("variant {vpath}({})", types.join(", ")));
                        }
                        Value::Object(o) if o.contains_key("struct") => {
                            self.out.insert(format!("variant {vpath} {{ .. }}"));
                            self.fields(&o["struct"]["fields"], &vpath);
                        }
                        _ => {
                            self.out.insert(format!("variant {vpath}"));
                        }
                    }
                }
                self.impls(&inner["impls"], path);
            }
            "function" => {
                self.out.insert(format!(
                    "fn {path}{}{}",
                    generics(&inner["generics"]),
                    signature(&inner["sig"])
                ));
            }
            "trait" => {
                self.out
                    .insert(format!("trait {path}{}", generics(&inner["generics"])));
                for member in inner["items"].as_array().into_iter().flatten() {
                    let member = id_key(member);
                    if let Some(m) = self.index.get(&member).copied() {
                        let name = m["name"].as_str().unwrap_or("_").to_owned();
                        self.item(&member, &format!("{path}::{name}"));
                    }
                }
            }
            "constant" => {
                self.out
                    .insert(format!("const {path}: {}", ty(&inner["type"])));
            }
            "static" => {
                self.out
                    .insert(format!("static {path}: {}", ty(&inner["type"])));
            }
            "type_alias" => {
                self.out.insert(format!(
                    "type {path}{} = {}",
                    generics(&inner["generics"]),
                    ty(&inner["type"])
                ));
            }
            "assoc_const" => {
                self.out
                    .insert(format!("const {path}: {}", ty(&inner["type"])));
            }
            "assoc_type" => {
                self.out.insert(format!("type {path}"));
            }
            "macro" | "proc_macro" => {
                self.out.insert(format!("macro {path}"));
            }
            other => {
                self.out.insert(format!("{other} {path}"));
            }
        }
    }

    /// The public items of a module, each under its name.
    fn children(&mut self, module: &Value, path: &str) {
        for child in module["items"].as_array().into_iter().flatten() {
            let child = id_key(child);
            let Some(c) = self.index.get(&child).copied() else {
                continue;
            };
            if c["visibility"] != "public" {
                continue;
            }
            if c["inner"].get("use").is_some() {
                self.item(&child, path);
            } else {
                let name = c["name"].as_str().unwrap_or("_").to_owned();
                self.item(&child, &format!("{path}::{name}"));
            }
        }
    }

    /// The public fields of a struct, union or struct-like variant.
    fn fields(&mut self, fields: &Value, path: &str) {
        for (position, field) in fields.as_array().into_iter().flatten().enumerate() {
            if field.is_null() {
                continue; // a private tuple field
            }
            let Some(f) = self.index.get(&id_key(field)).copied() else {
                continue;
            };
            if f["visibility"] != "public" && f["visibility"] != "default" {
                continue;
            }
            let name = f["name"]
                .as_str()
                .map(str::to_owned)
                .unwrap_or_else(|| position.to_string());
            self.out.insert(format!(
                "field {path}::{name}: {}",
                ty(&f["inner"]["struct_field"])
            ));
        }
    }

    /// A type's inherent methods and associated items, and the traits it implements (not auto traits or blanket
    /// impls, which follow from the rest).
    fn impls(&mut self, impls: &Value, path: &str) {
        for imp in impls.as_array().into_iter().flatten() {
            let Some(i) = self.index.get(&id_key(imp)).copied() else {
                continue;
            };
            let imp = &i["inner"]["impl"];
            if imp["is_synthetic"].as_bool() == Some(true) || !imp["blanket_impl"].is_null() {
                continue;
            }
            if imp["trait"].is_null() {
                for member in imp["items"].as_array().into_iter().flatten() {
                    let member = id_key(member);
                    let Some(m) = self.index.get(&member).copied() else {
                        continue;
                    };
                    if m["visibility"] != "public" {
                        continue;
                    }
                    let name = m["name"].as_str().unwrap_or("_").to_owned();
                    self.item(&member, &format!("{path}::{name}"));
                }
            } else {
                let negative = if imp["is_negative"].as_bool() == Some(true) {
                    "!"
                } else {
                    ""
                };
                self.out.insert(format!(
                    "impl {negative}{} for {path}",
                    path_type(&imp["trait"])
                ));
            }
        }
    }
}

/// A function's parameters and result.
fn signature(sig: &Value) -> String {
    let inputs: Vec<String> = sig["inputs"]
        .as_array()
        .into_iter()
        .flatten()
        .map(|pair| format!("{}: {}", pair[0].as_str().unwrap_or("_"), ty(&pair[1])))
        .collect();
    match &sig["output"] {
        Value::Null => format!("({})", inputs.join(", ")),
        output => format!("({}) -> {}", inputs.join(", "), ty(output)),
    }
}

/// Generic parameters with their bounds, `<...>`, or nothing.
fn generics(generics: &Value) -> String {
    let params: Vec<String> = generics["params"]
        .as_array()
        .into_iter()
        .flatten()
        .filter(|p| p["kind"]["type"]["is_synthetic"].as_bool() != Some(true))
        .map(|p| {
            let name = p["name"].as_str().unwrap_or("_");
            match p["kind"].get("type") {
                Some(t) => {
                    let bounds = bounds(&t["bounds"]);
                    if bounds.is_empty() {
                        name.to_owned()
                    } else {
                        format!("{name}: {bounds}")
                    }
                }
                None => match p["kind"].get("const") {
                    Some(c) => format!("const {name}: {}", ty(&c["type"])),
                    None => name.to_owned(),
                },
            }
        })
        .collect();
    let predicates: Vec<String> = generics["where_predicates"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|w| w.get("bound_predicate"))
        .map(|b| format!("{}: {}", ty(&b["type"]), bounds(&b["bounds"])))
        .collect();
    let mut text = String::new();
    if !params.is_empty() {
        text = format!("<{}>", params.join(", "));
    }
    if !predicates.is_empty() {
        text += &format!(" where {}", predicates.join(", "));
    }
    text
}

/// Trait and lifetime bounds joined with `+`.
fn bounds(bounds: &Value) -> String {
    let list: Vec<String> = bounds
        .as_array()
        .into_iter()
        .flatten()
        .map(|b| {
            if let Some(t) = b.get("trait_bound") {
                let modifier = if t["modifier"] == "maybe" { "?" } else { "" };
                format!("{modifier}{}", path_type(&t["trait"]))
            } else if let Some(l) = b.get("outlives") {
                l.as_str().unwrap_or("'_").to_owned()
            } else {
                "_".into()
            }
        })
        .collect();
    list.join(" + ")
}

/// A path with its generic arguments, as written.
fn path_type(path: &Value) -> String {
    // The last segment only: the path as written in the source says where the code lives, not the API.
    let name = path["path"]
        .as_str()
        .unwrap_or("_")
        .rsplit("::")
        .next()
        .unwrap_or("_");
    format!("{name}{}", generic_args(&path["args"]))
}

/// `<...>` or `(...) -> ...` after a path, or nothing.
fn generic_args(args: &Value) -> String {
    if let Some(a) = args.get("angle_bracketed") {
        let mut list: Vec<String> = a["args"]
            .as_array()
            .into_iter()
            .flatten()
            .map(|arg| {
                if let Some(t) = arg.get("type") {
                    ty(t)
                } else if let Some(l) = arg.get("lifetime") {
                    l.as_str().unwrap_or("'_").to_owned()
                } else if let Some(c) = arg.get("const") {
                    c["expr"].as_str().unwrap_or("_").to_owned()
                } else {
                    "_".into()
                }
            })
            .collect();
        for c in a["constraints"].as_array().into_iter().flatten() {
            let name = c["name"].as_str().unwrap_or("_");
            let binding = &c["binding"];
            if let Some(t) = binding.get("equality").and_then(|e| e.get("type")) {
                list.push(format!("{name} = {}", ty(t)));
            } else if let Some(b) = binding.get("constraint") {
                list.push(format!("{name}: {}", bounds(b)));
            }
        }
        if list.is_empty() {
            String::new()
        } else {
            format!("<{}>", list.join(", "))
        }
    } else if let Some(p) = args.get("parenthesized") {
        let inputs: Vec<String> = p["inputs"]
            .as_array()
            .into_iter()
            .flatten()
            .map(ty)
            .collect();
        match &p["output"] {
            Value::Null => format!("({})", inputs.join(", ")),
            output => format!("({}) -> {}", inputs.join(", "), ty(output)),
        }
    } else {
        String::new()
    }
}

/// A type as written.
fn ty(t: &Value) -> String {
    let Some((kind, inner)) = t.as_object().and_then(|o| o.iter().next()) else {
        return t.as_str().unwrap_or("_").to_owned();
    };
    match kind.as_str() {
        "resolved_path" => path_type(inner),
        "generic" | "primitive" => inner.as_str().unwrap_or("_").to_owned(),
        "tuple" => {
            let items: Vec<String> = inner.as_array().into_iter().flatten().map(ty).collect();
            format!("({})", items.join(", "))
        }
        "slice" => format!("[{}]", ty(inner)),
        "array" => format!(
            "[{}; {}]",
            ty(&inner["type"]),
            inner["len"].as_str().unwrap_or("_")
        ),
        "borrowed_ref" => {
            let lifetime = inner["lifetime"]
                .as_str()
                .map(|l| format!("{l} "))
                .unwrap_or_default();
            let mutable = if inner["is_mutable"].as_bool() == Some(true) {
                "mut "
            } else {
                ""
            };
            format!("&{lifetime}{mutable}{}", ty(&inner["type"]))
        }
        "raw_pointer" => {
            let mutable = if inner["is_mutable"].as_bool() == Some(true) {
                "mut"
            } else {
                "const"
            };
            format!("*{mutable} {}", ty(&inner["type"]))
        }
        "impl_trait" => format!("impl {}", bounds(inner)),
        "dyn_trait" => {
            let traits: Vec<String> = inner["traits"]
                .as_array()
                .into_iter()
                .flatten()
                .map(|p| path_type(&p["trait"]))
                .collect();
            let lifetime = inner["lifetime"]
                .as_str()
                .map(|l| format!(" + {l}"))
                .unwrap_or_default();
            format!("dyn {}{lifetime}", traits.join(" + "))
        }
        "function_pointer" => format!("fn{}", signature(&inner["sig"])),
        "qualified_path" => format!(
            "<{} as {}>::{}",
            ty(&inner["self_type"]),
            path_type(&inner["trait"]),
            inner["name"].as_str().unwrap_or("_")
        ),
        other => format!("<{other}>"),
    }
}
