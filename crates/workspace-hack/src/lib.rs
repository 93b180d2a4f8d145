//! No code: this crate only pins the features of shared dependencies (see its `Cargo.toml`)
//! so that `cargo test --workspace`, `cargo run` and the single-crate builds of `slamkit` and
//! `slamkit-py` compile each dependency once.
