//! Examples of `joint-runtime`; run them with `cargo run --release --example NAME`.
