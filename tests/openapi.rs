//! `openapi.yaml` and the router agree: every `.route("PATH", ...)` literal in
//! `src/api/**/*.rs` (subfolders too) is a path of the spec, and every spec path is routed.

use std::collections::BTreeSet;
use std::path::Path;

/// The path literals of `.route(` calls in a Rust source (whitespace after `(` allowed;
/// comment lines are skipped).
fn route_literals(src: &str) -> Vec<String> {
    let code: String = src
        .lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .map(|l| format!("{l}\n"))
        .collect();
    let mut out = Vec::new();
    let mut rest = code.as_str();
    while let Some(i) = rest.find(".route(") {
        rest = &rest[i + ".route(".len()..];
        let trimmed = rest.trim_start();
        if let Some(body) = trimmed.strip_prefix('"')
            && let Some(end) = body.find('"')
        {
            out.push(body[..end].to_string());
        }
    }
    out
}

/// The `.rs` files under `dir`, at any depth.
fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("the folder exists") {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

fn routed_paths() -> BTreeSet<String> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/api");
    let mut files = Vec::new();
    rust_files(&dir, &mut files);
    let mut paths = BTreeSet::new();
    for path in files {
        let src = std::fs::read_to_string(&path).unwrap();
        paths.extend(route_literals(&src));
    }
    paths
}

fn spec() -> serde_yaml::Value {
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("openapi.yaml"))
        .expect("openapi.yaml exists at the crate root");
    serde_yaml::from_str(&text).expect("openapi.yaml is valid YAML")
}

fn spec_paths() -> BTreeSet<String> {
    spec()["paths"]
        .as_mapping()
        .expect("openapi.yaml has a paths mapping")
        .keys()
        .map(|k| k.as_str().expect("path keys are strings").to_string())
        .collect()
}

#[test]
fn every_routed_path_is_in_the_spec_and_vice_versa() {
    let routed = routed_paths();
    let spec = spec_paths();
    assert!(
        routed.contains("/healthz") && routed.contains("/v1/machines/{machine}"),
        "{routed:?}"
    );
    // Routes declared in a subfolder (src/api/step_error/mod.rs) are scanned too.
    assert!(routed.contains("/v1/step-error"), "{routed:?}");
    let missing: Vec<_> = routed.difference(&spec).collect();
    let unrouted: Vec<_> = spec.difference(&routed).collect();
    assert!(
        missing.is_empty(),
        "routed but missing from openapi.yaml: {missing:?}"
    );
    assert!(
        unrouted.is_empty(),
        "in openapi.yaml but not routed: {unrouted:?}"
    );
}

#[test]
fn the_spec_is_openapi_3_with_operations_and_responses() {
    let spec = spec();
    assert!(
        spec["openapi"]
            .as_str()
            .is_some_and(|v| v.starts_with("3."))
    );
    for (path, item) in spec["paths"].as_mapping().unwrap() {
        let item = item.as_mapping().expect("path item is a mapping");
        let ops: Vec<_> = item
            .iter()
            .filter(|(k, _)| {
                matches!(
                    k.as_str(),
                    Some("get" | "put" | "post" | "delete" | "patch")
                )
            })
            .collect();
        assert!(!ops.is_empty(), "{path:?} has no operation");
        for (method, op) in ops {
            assert!(
                op["responses"].as_mapping().is_some_and(|r| !r.is_empty()),
                "{path:?} {method:?} has no responses"
            );
        }
    }
}

#[test]
fn route_literal_scanner_handles_formatting() {
    let src = "//! `.route(\"/doc\", get(..))`\nRouter::new()\n  .route(\"/a\", get(x))\n  .route(\n        \"/b/{id}\",\n get(y))";
    assert_eq!(
        route_literals(src),
        vec!["/a".to_string(), "/b/{id}".to_string()]
    );
}
