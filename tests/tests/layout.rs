//! The workspace's seams, checked from its own metadata and sources:
//! - the numerical core (`mmt`), the nodes (`node`) and the wire protocol (`protocol`) never
//!   depend on an async runtime, a network stack, a plotting library, a command-line parser, the
//!   C library or the netem shim (`cargo metadata`'s resolved normal dependencies);
//! - outside tests, no source file is over 600 lines and no function over 80 (parsed with `syn`,
//!   `#[cfg(test)]` items left out).

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::collections::{BTreeSet, HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;
use syn::spanned::Spanned;
use syn::visit::Visit;

/// Crates that must stay free of I/O, runtimes and tools.
const PURE: [&str; 3] = ["mmt", "node", "protocol"];
/// What they must never depend on, directly or through another crate.
const FORBIDDEN: [&str; 6] = ["tokio", "quinn", "rustls", "plotters", "clap", "netem"];
/// What they must never depend on directly. `libc` reaches `mmt` through `kiddo`, whose
/// x86-64 build always links the `generator` crate; no code of ours calls it.
const FORBIDDEN_DIRECT: [&str; 1] = ["libc"];
/// The only paths by which a forbidden-direct crate may be reached, as (from, to) edges.
const ALLOWED_TRANSITIVE: [(&str, &str); 1] = [("generator", "libc")];

const MAX_FILE_LINES: usize = 600;
const MAX_FN_LINES: usize = 80;

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the tests crate is in the workspace root")
        .to_path_buf()
}

fn metadata() -> Value {
    let out = Command::new(env!("CARGO"))
        .args(["metadata", "--format-version", "1", "--locked"])
        .current_dir(workspace_root())
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "cargo metadata: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("cargo metadata prints JSON")
}

/// Package id → name, and id → the ids of its normal (not dev, not build) dependencies.
fn normal_graph(meta: &Value) -> (HashMap<String, String>, HashMap<String, Vec<String>>) {
    let names = meta["packages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            (
                p["id"].as_str().unwrap().to_owned(),
                p["name"].as_str().unwrap().to_owned(),
            )
        })
        .collect();
    let edges = meta["resolve"]["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| {
            let deps = n["deps"]
                .as_array()
                .unwrap()
                .iter()
                .filter(|d| {
                    d["dep_kinds"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .any(|k| k["kind"].is_null())
                })
                .map(|d| d["pkg"].as_str().unwrap().to_owned())
                .collect();
            (n["id"].as_str().unwrap().to_owned(), deps)
        })
        .collect();
    (names, edges)
}

#[test]
fn the_core_the_nodes_and_the_protocol_depend_on_no_runtime_network_plot_cli_or_shim() {
    let meta = metadata();
    let (names, edges) = normal_graph(&meta);
    let id_of = |name: &str| {
        names
            .iter()
            .find(|(_, n)| n.as_str() == name)
            .map(|(id, _)| id.clone())
            .unwrap_or_else(|| panic!("no package {name}"))
    };
    let mut problems = Vec::new();
    for pure in PURE {
        let root = id_of(pure);
        for direct in &edges[&root] {
            let name = &names[direct];
            if FORBIDDEN.contains(&name.as_str()) || FORBIDDEN_DIRECT.contains(&name.as_str()) {
                problems.push(format!("{pure} depends on {name} directly"));
            }
        }
        // Breadth-first over normal dependencies, remembering who brought each crate in.
        let mut parent: HashMap<String, String> = HashMap::new();
        let mut queue = VecDeque::from([root.clone()]);
        while let Some(id) = queue.pop_front() {
            for dep in &edges[&id] {
                if dep != &root && !parent.contains_key(dep) {
                    parent.insert(dep.clone(), id.clone());
                    queue.push_back(dep.clone());
                }
            }
        }
        for (dep, via) in &parent {
            let (name, via_name) = (&names[dep], &names[via]);
            let forbidden = FORBIDDEN.contains(&name.as_str())
                || (FORBIDDEN_DIRECT.contains(&name.as_str())
                    && !ALLOWED_TRANSITIVE.contains(&(via_name.as_str(), name.as_str())));
            if forbidden {
                problems.push(format!("{pure} depends on {name} (through {via_name})"));
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The test kit is a dev-dependency only: no library or binary of the workspace links it.
#[test]
fn no_crate_depends_on_the_test_kit_outside_its_tests() {
    let meta = metadata();
    let packages = meta["packages"].as_array().unwrap();
    let members = meta["workspace_members"].as_array().unwrap();
    let mut problems = Vec::new();
    for package in packages.iter().filter(|p| members.contains(&p["id"])) {
        for dep in package["dependencies"].as_array().unwrap() {
            if dep["name"] == "testkit" && dep["kind"] != "dev" {
                problems.push(package["name"].as_str().unwrap().to_owned());
            }
        }
    }
    assert!(
        problems.is_empty(),
        "testkit as a normal or build dependency of {problems:?}"
    );
}

/// Every `.rs` file of the workspace's libraries and binaries: `src/` of each member, without
/// test modules in their own files (`tests.rs`, `tests/`), benches, examples or the fuzz crate.
fn sources() -> Vec<PathBuf> {
    let meta = metadata();
    let mut files = Vec::new();
    for member in meta["workspace_members"].as_array().unwrap() {
        let package = meta["packages"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["id"] == *member)
            .unwrap();
        let manifest = Path::new(package["manifest_path"].as_str().unwrap());
        collect(&manifest.parent().unwrap().join("src"), &mut files);
    }
    files.sort();
    files
}

fn collect(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        if path.is_dir() {
            if name != "tests" {
                collect(&path, out);
            }
        } else if name.ends_with(".rs") && name != "tests.rs" {
            out.push(path);
        }
    }
}

/// Lines and long functions of one file, test items left out.
#[derive(Default)]
struct Measure {
    test_lines: usize,
    long_fns: Vec<(String, usize, usize)>,
}

fn is_cfg_test(attrs: &[syn::Attribute]) -> bool {
    attrs.iter().any(|a| {
        a.path().is_ident("cfg")
            && a.parse_args::<syn::Meta>()
                .is_ok_and(|m| m.path().is_ident("test"))
    })
}

fn lines(span: proc_macro2::Span) -> usize {
    span.end().line - span.start().line + 1
}

impl Measure {
    fn function(&mut self, name: &syn::Ident, span: proc_macro2::Span) {
        let n = lines(span);
        if n > MAX_FN_LINES {
            self.long_fns.push((name.to_string(), span.start().line, n));
        }
    }
}

impl<'ast> Visit<'ast> for Measure {
    fn visit_item(&mut self, item: &'ast syn::Item) {
        let attrs = match item {
            syn::Item::Mod(m) => &m.attrs,
            syn::Item::Fn(f) => &f.attrs,
            syn::Item::Impl(i) => &i.attrs,
            syn::Item::Use(u) => &u.attrs,
            syn::Item::Const(c) => &c.attrs,
            syn::Item::Struct(s) => &s.attrs,
            _ => return syn::visit::visit_item(self, item),
        };
        if is_cfg_test(attrs) {
            self.test_lines += lines(item.span());
            return;
        }
        syn::visit::visit_item(self, item);
    }

    fn visit_item_fn(&mut self, f: &'ast syn::ItemFn) {
        self.function(&f.sig.ident, f.span());
        syn::visit::visit_item_fn(self, f);
    }

    fn visit_impl_item_fn(&mut self, f: &'ast syn::ImplItemFn) {
        if is_cfg_test(&f.attrs) {
            return;
        }
        self.function(&f.sig.ident, f.span());
        syn::visit::visit_impl_item_fn(self, f);
    }

    fn visit_trait_item_fn(&mut self, f: &'ast syn::TraitItemFn) {
        if f.default.is_some() {
            self.function(&f.sig.ident, f.span());
        }
        syn::visit::visit_trait_item_fn(self, f);
    }
}

#[test]
fn no_source_file_is_over_600_lines_and_no_function_over_80() {
    let root = workspace_root();
    let mut problems = BTreeSet::new();
    let files = sources();
    assert!(files.len() > 100, "found only {} source files", files.len());
    for path in files {
        let text = std::fs::read_to_string(&path).unwrap();
        let file = syn::parse_file(&text)
            .unwrap_or_else(|e| panic!("{}: does not parse: {e}", path.display()));
        let mut m = Measure::default();
        m.visit_file(&file);
        let shown = path
            .strip_prefix(&root)
            .unwrap_or(&path)
            .display()
            .to_string();
        let code_lines = text.lines().count().saturating_sub(m.test_lines);
        if code_lines > MAX_FILE_LINES {
            problems.insert(format!(
                "{shown}: {code_lines} lines outside tests (at most {MAX_FILE_LINES})"
            ));
        }
        for (name, line, n) in m.long_fns {
            problems.insert(format!(
                "{shown}:{line}: fn {name} is {n} lines (at most {MAX_FN_LINES})"
            ));
        }
    }
    assert!(
        problems.is_empty(),
        "{} problems:\n{}",
        problems.len(),
        problems.into_iter().collect::<Vec<_>>().join("\n")
    );
}

#[test]
fn the_size_check_sees_functions_and_leaves_test_modules_out() {
    let text = format!(
        "fn short() {{}}\nfn long() {{\n{}}}\n#[cfg(test)]\nmod tests {{\n    fn long_test() {{\n{}    }}\n}}\nimpl S {{ fn method() {{\n{}}} }}\n",
        "    let _ = 1;\n".repeat(MAX_FN_LINES),
        "        let _ = 1;\n".repeat(MAX_FN_LINES),
        "    let _ = 2;\n".repeat(MAX_FN_LINES),
    );
    let file = syn::parse_file(&text).unwrap();
    let mut m = Measure::default();
    m.visit_file(&file);
    let names: Vec<&str> = m.long_fns.iter().map(|(n, ..)| n.as_str()).collect();
    assert_eq!(names, ["long", "method"]);
    assert_eq!(m.test_lines, MAX_FN_LINES + 5);
}
