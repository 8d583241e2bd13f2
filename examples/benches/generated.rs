//! Criterion benchmarks of the generated code (being written).

fn main() {}
