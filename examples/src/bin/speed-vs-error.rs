//! The speed-against-error report (being written).

fn main() {}
