//! Comments that name a twin must name something that exists.
//!
//! The WGSL kernels and their Rust counterparts point at each other in comments ("Rust twin:
//! ray::intersect_triangle", "WGSL twin `Hit` in wgsl/samples.wgsl"); after a rename such a
//! pointer goes stale without any compiler noticing. This test resolves every one:
//!
//! - "Rust twin", "Rust twins", "CPU twin", "CPU twins" (in wgsl/*.wgsl, src/**/*.rs and
//!   README.md), with or without a colon, followed by an item path, optionally in backticks;
//!   the plural by a list separated by commas or "and". `a::b::item` (a leading `crate::` or
//!   `src/` allowed) must be defined in src/a/b.rs or src/a/b/mod.rs; `[a::]Type::method` in a
//!   file (src/a.rs, or any file under src/ without a module) that defines both the type and the
//!   method. Paths need at least two segments.
//! - "WGSL twin" (in the same files), followed by an optional name and an optional "in
//!   wgsl/<file>.wgsl": the name, or else the name of the Rust item the comment documents, must
//!   be a struct, fn, const, var, alias or override of that file (of any wgsl/*.wgsl without one).
//! - Every `wgsl/<name>.wgsl` mentioned in README.md, src/ or wgsl/ must exist.
//!
//! The parser is deliberately simple and strict: anything after one of these phrases that it
//! cannot resolve fails the test with the file, line and text.

use std::fs;
use std::path::{Path, PathBuf};

/// One scanned file: its path relative to the crate root, and its text.
struct Source {
    path: String,
    text: String,
}

/// Everything a reference can resolve against.
struct Tree {
    /// src/**/*.rs, path relative to the crate root.
    rust: Vec<Source>,
    /// wgsl/*.wgsl.
    wgsl: Vec<Source>,
    readme: Source,
}

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Files under `dir` (recursively) whose names end in `extension`, sorted by path.
fn sources(dir: &str, extension: &str) -> Vec<Source> {
    fn walk(dir: &Path, extension: &str, out: &mut Vec<PathBuf>) {
        for entry in fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(&path, extension, out);
            } else if path.extension().is_some_and(|e| e == extension) {
                out.push(path);
            }
        }
    }
    let mut paths = Vec::new();
    walk(&root().join(dir), extension, &mut paths);
    paths.sort();
    paths
        .into_iter()
        .map(|path| Source {
            path: path
                .strip_prefix(root())
                .unwrap()
                .to_string_lossy()
                .replace('\\', "/"),
            text: fs::read_to_string(&path).unwrap(),
        })
        .collect()
}

fn tree() -> Tree {
    Tree {
        rust: sources("src", "rs"),
        wgsl: sources("wgsl", "wgsl"),
        readme: Source {
            path: "README.md".into(),
            text: fs::read_to_string(root().join("README.md")).unwrap(),
        },
    }
}

impl Tree {
    /// Every file whose references are checked: wgsl/, src/ and the README.
    fn scanned(&self) -> impl Iterator<Item = &Source> {
        self.wgsl
            .iter()
            .chain(&self.rust)
            .chain(std::iter::once(&self.readme))
    }
}

fn is_ident_start(c: char) -> bool {
    c.is_ascii_alphabetic() || c == '_'
}

fn is_ident(s: &str) -> bool {
    s.starts_with(is_ident_start) && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// The identifier at the start of `s`, if any.
fn leading_ident(s: &str) -> Option<&str> {
    let end = s
        .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .unwrap_or(s.len());
    Some(&s[..end]).filter(|name| is_ident(name))
}

/// Whether a line of Rust defines `name` with one of `keywords` (`fn`, `struct`, ...), after
/// any visibility and `const`/`async`/`unsafe`/`extern "C"` qualifiers.
fn rust_defines(text: &str, keywords: &[&str], name: &str) -> bool {
    text.lines()
        .any(|line| rust_definition(line, keywords) == Some(name))
}

/// The name a line of Rust defines with one of `keywords`, if it is such a definition.
fn rust_definition<'a>(line: &'a str, keywords: &[&str]) -> Option<&'a str> {
    let mut t = line.trim_start();
    if let Some(rest) = t.strip_prefix("pub") {
        t = match rest.strip_prefix('(') {
            Some(scope) => &scope[scope.find(')')? + 1..],
            None if rest.starts_with(' ') => rest,
            None => return None,
        }
        .trim_start();
    }
    loop {
        let before = t;
        for qualifier in ["async ", "unsafe ", "extern \"C\" "] {
            t = t.strip_prefix(qualifier).unwrap_or(t).trim_start();
        }
        if let Some(rest) = t.strip_prefix("const ") {
            if ["fn ", "async ", "unsafe "]
                .iter()
                .any(|q| rest.starts_with(q))
            {
                t = rest;
            }
        }
        if t == before {
            break;
        }
    }
    keywords.iter().find_map(|keyword| {
        let rest = t.strip_prefix(keyword)?.strip_prefix(' ')?.trim_start();
        let rest = rest.strip_prefix("mut ").unwrap_or(rest);
        leading_ident(rest)
    })
}

/// Whether WGSL text defines `name` at module scope.
fn wgsl_defines(text: &str, name: &str) -> bool {
    text.lines().any(|line| {
        let t = line.trim_start();
        ["struct", "fn", "const", "alias", "override", "var"]
            .iter()
            .any(|keyword| {
                let Some(rest) = t.strip_prefix(keyword) else {
                    return false;
                };
                let rest = match rest.strip_prefix('<') {
                    Some(access) if *keyword == "var" => match access.find('>') {
                        Some(end) => &access[end + 1..],
                        None => return false,
                    },
                    _ => rest,
                };
                rest.starts_with(' ') && leading_ident(rest.trim_start()) == Some(name)
            })
    })
}

const ITEM_KEYWORDS: [&str; 9] = [
    "fn", "struct", "enum", "const", "static", "type", "trait", "mod", "union",
];
const TYPE_KEYWORDS: [&str; 4] = ["struct", "enum", "trait", "union"];
const ASSOCIATED_KEYWORDS: [&str; 3] = ["fn", "const", "type"];

/// The file of module `a::b` (src/a/b.rs or src/a/b/mod.rs).
fn module_file<'t>(tree: &'t Tree, modules: &[&str]) -> Result<&'t Source, String> {
    let base = format!("src/{}", modules.join("/"));
    let candidates = [format!("{base}.rs"), format!("{base}/mod.rs")];
    tree.rust
        .iter()
        .find(|s| candidates.contains(&s.path))
        .ok_or_else(|| format!("neither {} nor {} exists", candidates[0], candidates[1]))
}

/// Resolves a Rust item path as written after "Rust twin" (see the module comment).
fn resolve_rust(tree: &Tree, written: &str) -> Result<(), String> {
    let mut path = written.strip_prefix("crate::").unwrap_or(written);
    let file_form;
    if let Some(rest) = path.strip_prefix("src/") {
        file_form = rest.replace(".rs::", "::").replace('/', "::");
        path = &file_form;
    }
    let segments: Vec<&str> = path.split("::").collect();
    if segments.len() < 2 || !segments.iter().all(|s| is_ident(s)) {
        return Err("not an item path (`module::item` or `Type::method`)".into());
    }
    let n = segments.len();
    let item = segments[n - 1];
    let parent = segments[n - 2];
    if parent.starts_with(|c: char| c.is_ascii_uppercase()) {
        // Type::method: a file that defines both.
        let modules = &segments[..n - 2];
        let candidates: Vec<&Source> = if modules.is_empty() {
            tree.rust.iter().collect()
        } else {
            vec![module_file(tree, modules)?]
        };
        let found = candidates.iter().any(|s| {
            rust_defines(&s.text, &TYPE_KEYWORDS, parent)
                && rust_defines(&s.text, &ASSOCIATED_KEYWORDS, item)
        });
        if found {
            Ok(())
        } else {
            Err(format!(
                "no file{} defines both `struct|enum|trait {parent}` and `fn {item}`",
                if modules.is_empty() {
                    " under src/".to_string()
                } else {
                    format!(" of module {}", modules.join("::"))
                }
            ))
        }
    } else {
        let file = module_file(tree, &segments[..n - 1])?;
        if rust_defines(&file.text, &ITEM_KEYWORDS, item) {
            Ok(())
        } else {
            Err(format!("{} does not define `{item}`", file.path))
        }
    }
}

/// The text of a comment line without its marker (`//`, `///`, `//!`, `*`), or the whole line
/// where it has none (Markdown).
fn comment_text(line: &str) -> &str {
    let t = line.trim_start();
    ["//!", "///", "//", "* "]
        .iter()
        .find_map(|marker| t.strip_prefix(marker))
        .unwrap_or(t)
}

/// A reference token at the start of `s` (after whitespace): a path in backticks, or a run of
/// path characters without trailing punctuation. Returns the token and what follows it.
fn take_token(s: &str) -> Option<(&str, &str)> {
    let s = s.trim_start();
    if let Some(quoted) = s.strip_prefix('`') {
        let end = quoted.find('`')?;
        return Some((&quoted[..end], &quoted[end + 1..]));
    }
    let end = s
        .find(|c: char| !(c.is_ascii_alphanumeric() || matches!(c, '_' | ':' | '/' | '.')))
        .unwrap_or(s.len());
    let token = s[..end].trim_end_matches(['.', ':']);
    Some((token, &s[end..])).filter(|(t, _)| !t.is_empty())
}

/// The items of a list after its first (`, b`, `, and c`, ` and d`), while each is a path in
/// backticks or with `::`.
fn further_items(mut after: &str) -> Vec<String> {
    let mut items = Vec::new();
    loop {
        let t = after.trim_start();
        let Some(t) = t.strip_prefix(',').or_else(|| t.strip_prefix("and ")) else {
            break;
        };
        let t = t.trim_start();
        let t = t.strip_prefix("and ").unwrap_or(t).trim_start();
        match take_token(t) {
            Some((token, rest)) if t.starts_with('`') || token.contains("::") => {
                items.push(token.to_string());
                after = rest;
            }
            _ => break,
        }
    }
    items
}

/// One reference, with where it was written.
struct Reference {
    file: String,
    line: usize,
    text: String,
}

impl Reference {
    fn fail(&self, why: impl std::fmt::Display) -> String {
        format!("{}:{}: {:?}: {why}", self.file, self.line, self.text.trim())
    }
}

/// The references after "Rust twin(s)"/"CPU twin(s)" in one file, each as
/// (where, Ok(item path) or Err(why it cannot be read)).
fn rust_twin_references(source: &Source) -> Vec<(Reference, Result<String, String>)> {
    let lines: Vec<&str> = source.text.lines().collect();
    let mut found = Vec::new();
    for (index, line) in lines.iter().enumerate() {
        for phrase in ["Rust twin", "CPU twin"] {
            for (at, _) in line.match_indices(phrase) {
                let before = line[..at].chars().next_back();
                let mut rest = &line[at + phrase.len()..];
                let plural = rest.starts_with('s');
                if plural {
                    rest = &rest[1..];
                }
                if before.is_some_and(|c| c.is_ascii_alphanumeric())
                    || rest.starts_with(|c: char| c.is_ascii_alphanumeric())
                {
                    continue;
                }
                // A reference may run on to the next comment line.
                let mut text = rest.strip_prefix(':').unwrap_or(rest).to_string();
                if let Some(next) = lines.get(index + 1) {
                    text.push(' ');
                    text.push_str(comment_text(next));
                }
                let at_line = || Reference {
                    file: source.path.clone(),
                    line: index + 1,
                    text: line.to_string(),
                };
                let Some((first, after)) = take_token(&text) else {
                    found.push((at_line(), Err(format!("no item path after {phrase:?}"))));
                    continue;
                };
                found.push((at_line(), Ok(first.to_string())));
                if plural {
                    for token in further_items(after) {
                        found.push((at_line(), Ok(token)));
                    }
                }
            }
        }
    }
    found
}

/// The name of the Rust item that the doc comment containing line `index` documents.
fn documented_item<'a>(lines: &[&'a str], index: usize) -> Option<&'a str> {
    lines[index + 1..]
        .iter()
        .map(|l| l.trim_start())
        .find(|l| !(l.starts_with("//") || l.starts_with("#[") || l.is_empty()))
        .and_then(|l| rust_definition(l, &ITEM_KEYWORDS))
}

/// Every error in the "WGSL twin" references of one file.
fn wgsl_twin_errors(tree: &Tree, source: &Source) -> Vec<String> {
    let lines: Vec<&str> = source.text.lines().collect();
    let mut errors = Vec::new();
    for (index, line) in lines.iter().enumerate() {
        for (at, _) in line.match_indices("WGSL twin") {
            let reference = Reference {
                file: source.path.clone(),
                line: index + 1,
                text: line.to_string(),
            };
            let mut rest = &line[at + "WGSL twin".len()..];
            rest = rest.strip_prefix('s').unwrap_or(rest);
            let mut text = rest.strip_prefix(':').unwrap_or(rest).to_string();
            if let Some(next) = lines.get(index + 1) {
                text.push(' ');
                text.push_str(comment_text(next));
            }
            let mut t = text.trim_start();
            let mut name = None;
            if let Some(quoted) = t.strip_prefix('`') {
                let end = quoted.find('`').unwrap_or(quoted.len());
                name = Some(quoted[..end].to_string());
                t = quoted.get(end + 1..).unwrap_or("").trim_start();
            } else if let Some(word) = leading_ident(t).filter(|w| *w != "in") {
                name = Some(word.to_string());
                t = t[word.len()..].trim_start();
            }
            let file = t.strip_prefix("in ").map(|t| {
                let word = t.split_whitespace().next().unwrap_or("");
                word.trim_matches(|c: char| matches!(c, '`' | '.' | ',' | ';' | ':' | ')'))
                    .to_string()
            });
            if let Some(file) = file.as_ref().filter(|f| !f.ends_with(".wgsl")) {
                errors.push(reference.fail(format!("{file:?} is not a wgsl/<name>.wgsl file")));
                continue;
            }
            if name.is_none() && file.is_none() {
                errors.push(reference.fail("names neither a WGSL item nor a wgsl/ file"));
                continue;
            }
            let name = match name {
                Some(name) => name,
                None => match documented_item(&lines, index) {
                    Some(item) => item.to_string(),
                    None => {
                        errors.push(reference.fail(
                            "names no WGSL item and documents no Rust item to take the name of",
                        ));
                        continue;
                    }
                },
            };
            let candidates: Vec<&Source> = match &file {
                Some(file) => match tree.wgsl.iter().find(|s| &s.path == file) {
                    Some(s) => vec![s],
                    None => {
                        errors.push(reference.fail(format!("{file} does not exist")));
                        continue;
                    }
                },
                None => tree.wgsl.iter().collect(),
            };
            if !candidates.iter().any(|s| wgsl_defines(&s.text, &name)) {
                errors.push(reference.fail(format!(
                    "`{name}` is not a struct, fn, const or var of {}",
                    file.as_deref().unwrap_or("any wgsl/*.wgsl")
                )));
            }
        }
    }
    errors
}

/// Every error in the twin references of one file.
fn twin_errors(tree: &Tree, source: &Source) -> Vec<String> {
    let mut errors: Vec<String> = rust_twin_references(source)
        .into_iter()
        .filter_map(|(reference, path)| match path {
            Ok(path) => resolve_rust(tree, &path)
                .err()
                .map(|why| reference.fail(format!("`{path}`: {why}"))),
            Err(why) => Some(reference.fail(why)),
        })
        .collect();
    errors.extend(wgsl_twin_errors(tree, source));
    errors
}

/// Every `wgsl/<name>.wgsl` mentioned in one file that does not exist.
fn missing_wgsl_files(source: &Source) -> Vec<String> {
    let mut errors = Vec::new();
    for (index, line) in source.text.lines().enumerate() {
        for (at, _) in line.match_indices("wgsl/") {
            let rest = &line[at + "wgsl/".len()..];
            let name_end = rest
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == '-'))
                .unwrap_or(rest.len());
            if name_end == 0 || !rest[name_end..].starts_with(".wgsl") {
                continue;
            }
            let file = format!("wgsl/{}.wgsl", &rest[..name_end]);
            if !root().join(&file).is_file() {
                errors.push(format!(
                    "{}:{}: {:?}: {file} does not exist",
                    source.path,
                    index + 1,
                    line.trim()
                ));
            }
        }
    }
    errors
}

fn source(path: &str, text: &str) -> Source {
    Source {
        path: path.into(),
        text: text.into(),
    }
}

#[test]
fn every_twin_reference_names_an_item_that_exists() {
    let tree = tree();
    let errors: Vec<String> = tree.scanned().flat_map(|s| twin_errors(&tree, s)).collect();
    assert!(
        errors.is_empty(),
        "stale twin references:\n{}",
        errors.join("\n")
    );
    // Not vacuous: the scan sees references of both kinds.
    let rust: usize = tree.scanned().map(|s| rust_twin_references(s).len()).sum();
    let wgsl: usize = tree
        .scanned()
        .map(|s| s.text.matches("WGSL twin").count())
        .sum();
    assert!(rust > 0 && wgsl > 0, "{rust} Rust twins, {wgsl} WGSL twins");
}

#[test]
fn every_mentioned_wgsl_file_exists() {
    let tree = tree();
    let errors: Vec<String> = tree.scanned().flat_map(missing_wgsl_files).collect();
    assert!(
        errors.is_empty(),
        "mentions of missing kernels:\n{}",
        errors.join("\n")
    );
}

#[test]
fn every_form_of_reference_resolves() {
    let tree = tree();
    let text = "\
// Rust twin: ray::intersect_triangle.
// Rust twin bvh::gpu::GpuNode:
// CPU twin `bake::cpu::trace_visibility`
// Rust twins: bake::cpu::trace_visibility, bake::bounce::hits_and_visibility.
// Rust twins: crate::bake::cpu::project_visibility and src/bake/bounce.rs::apply_cpu; done.
// Rust twin: Bvh::traverse, which visits the same nodes.
// Rust twin: bvh::Bvh::traverse.
// CPU twins:
//   ray::intersect_triangle, `sampling::tangent_frame`.
";
    let file = source("wgsl/example.wgsl", text);
    let references: Vec<String> = rust_twin_references(&file)
        .into_iter()
        .map(|(_, path)| path.unwrap())
        .collect();
    assert_eq!(
        references,
        [
            "ray::intersect_triangle",
            "bvh::gpu::GpuNode",
            "bake::cpu::trace_visibility",
            "bake::cpu::trace_visibility",
            "bake::bounce::hits_and_visibility",
            "crate::bake::cpu::project_visibility",
            "src/bake/bounce.rs::apply_cpu",
            "Bvh::traverse",
            "bvh::Bvh::traverse",
            "ray::intersect_triangle",
            "sampling::tangent_frame",
        ]
    );
    assert_eq!(twin_errors(&tree, &file), Vec::<String>::new());

    let rust = source(
        "src/example.rs",
        "/// The closest hit; WGSL twin `Hit` in wgsl/samples.wgsl.\n\
         pub struct Hit;\n\
         /// Uniforms of the gather kernel; WGSL twin in wgsl/gather.wgsl.\n\
         #[repr(C)]\n\
         pub struct GatherParams;\n\
         // WGSL twin: tangent_frame.\n",
    );
    assert_eq!(twin_errors(&tree, &rust), Vec::<String>::new());
}

#[test]
fn stale_references_fail_with_file_line_and_text() {
    let tree = tree();
    let stale = [
        // The hits kernel's helper, gone since the hits moved into the visibility kernel.
        ("// Rust twin: bake::bounce::vertex_hits", "vertex_hits"),
        ("// Rust twin: bake::gpu::GpuNode.", "GpuNode"),
        ("// Rust twin: output::write_glb.", "src/output.rs"),
        (
            "// Rust twins: bake::cpu::trace_visibility, bounce::NO_HIT.",
            "NO_HIT",
        ),
        ("// Rust twin: Bvh::walk.", "fn walk"),
        ("// CPU twin: intersect_triangle.", "not an item path"),
        ("// the CPU twin of this kernel", "not an item path"),
        ("// Rust twin:", "no item path"),
    ];
    for (line, expect) in stale {
        let file = source("wgsl/example.wgsl", &format!("// first\n{line}\n"));
        let errors = twin_errors(&tree, &file);
        assert_eq!(errors.len(), 1, "{line}: {errors:?}");
        assert!(
            errors[0].starts_with("wgsl/example.wgsl:2: ")
                && errors[0].contains(line)
                && errors[0].contains(expect),
            "{line}: {}",
            errors[0]
        );
    }

    let wgsl_stale = [
        (
            "/// WGSL twin `Hits` in wgsl/visibility.wgsl.\npub struct Hit;",
            "`Hits`",
        ),
        (
            "/// WGSL twin in wgsl/hits.wgsl.\npub struct Hit;",
            "wgsl/hits.wgsl does not exist",
        ),
        (
            "/// WGSL twin in wgsl/gather.wgsl.\npub struct Gather;",
            "`Gather`",
        ),
        ("// WGSL twin: vertex_hits.", "vertex_hits"),
        ("// the WGSL twin", "neither"),
        (
            "/// WGSL twin in the kernel.\npub struct Hit;",
            "not a wgsl/<name>.wgsl",
        ),
    ];
    for (text, expect) in wgsl_stale {
        let file = source("src/example.rs", text);
        let errors = twin_errors(&tree, &file);
        assert_eq!(errors.len(), 1, "{text}: {errors:?}");
        assert!(
            errors[0].starts_with("src/example.rs:1: ") && errors[0].contains(expect),
            "{text}: {}",
            errors[0]
        );
    }

    let file = source(
        "src/example.rs",
        "//! Kernels in wgsl/.\n// Counted by wgsl/hits.wgsl, read by wgsl/visibility.wgsl.\n",
    );
    assert_eq!(
        missing_wgsl_files(&file),
        [
            "src/example.rs:2: \"// Counted by wgsl/hits.wgsl, read by wgsl/visibility.wgsl.\": \
          wgsl/hits.wgsl does not exist"
        ]
    );
}
