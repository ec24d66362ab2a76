//! Running the `firelink` binary as a user runs it, for the end-to-end
//! tests: its output, its JSON, its refusals.
#![allow(dead_code)]

use std::process::{Command, Output};

use serde_json::Value;

/// `firelink ARGS`, progress lines off.
pub fn firelink(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_firelink"))
        .args(args)
        .env("FIRELINK_QUIET", "1")
        .output()
        .expect("run firelink")
}

/// What `firelink ARGS` printed on stdout; it must succeed.
pub fn ok(args: &[&str]) -> String {
    let out = firelink(args);
    assert!(
        out.status.success(),
        "{args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("UTF-8 output")
}

/// The one JSON object `firelink ARGS` printed; it must succeed.
pub fn json(args: &[&str]) -> Value {
    serde_json::from_str(&ok(args)).expect("one JSON object")
}

/// `firelink ARGS` must fail, saying `needle` on stderr; returns stderr.
pub fn fails(args: &[&str], needle: &str) -> String {
    let out = firelink(args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "{args:?} should fail");
    assert!(err.contains(needle), "{args:?}: {err:?} lacks {needle:?}");
    err
}

/// The name libtest runs the test `function` of the module at
/// `module_path` (its `module_path!()`) by: the module path without the
/// test binary's own name in front, then the function, as `--exact` wants
/// it when a test runs its own binary again as a child process.
pub fn libtest_name(module_path: &str, function: &str) -> String {
    match module_path.split_once("::") {
        Some((_binary, module)) => format!("{module}::{function}"),
        None => function.to_string(),
    }
}
