//! Running the `mesobake` binary from integration tests.

use std::process::{Command, Output};

/// Runs `mesobake` with `args`.
pub fn mesobake(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_mesobake"))
        .args(args)
        .output()
        .unwrap()
}

/// Runs `mesobake` with `args` and asserts success, showing stderr otherwise.
pub fn succeeds(args: &[&str]) -> Output {
    let out = mesobake(args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Asserts that each command fails with a message containing its expected text, and never
/// with a panic.
pub fn each_fails_with(cases: &[(Vec<&str>, &str)]) {
    for (args, want) in cases {
        let out = mesobake(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(want),
            "{args:?}: {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
    }
}
