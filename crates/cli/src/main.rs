//! The `slamkit` command-line tool.
fn main() {}
