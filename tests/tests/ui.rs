//! Compile-fail tests of the derive's error messages, and a compile-pass test.
//!
//! Regenerate the expected output with
//! `TRYBUILD=overwrite cargo test -p joint-tests --test ui`.

#[test]
fn ui() {
    let t = trybuild::TestCases::new();
    t.pass("tests/ui/pass*.rs");
    t.compile_fail("tests/ui/fail_*.rs");
}
