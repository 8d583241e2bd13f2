//! Compile-time geometry of constant parameters, in f64.

/// `[x, y, z]` as written, for messages.
pub fn list(v: &[f64]) -> String {
    format!("[{}]", v.iter().map(|x| format!("{x}")).collect::<Vec<_>>().join(", "))
}

/// `a · b`.
pub fn dot3(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `|a|`.
pub fn norm3(a: &[f64]) -> f64 {
    dot3(a, a).sqrt()
}

/// `a × b`.
pub fn cross3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// The cosine of the angle between `a` and `b`.
pub fn cosine(a: &[f64], b: &[f64]) -> f64 {
    dot3(a, b) / (norm3(a) * norm3(b))
}

/// The compile-time twin of `joint_runtime::perpendicular_pair` (same rule, f64).
pub fn perpendicular_pair(d: &[f64]) -> ([f64; 3], [f64; 3]) {
    let n = norm3(d);
    let u = [d[0] / n, d[1] / n, d[2] / n];
    let (ax, ay, az) = (u[0].abs(), u[1].abs(), u[2].abs());
    let e = if ax <= ay && ax <= az {
        [1.0, 0.0, 0.0]
    } else if ay <= az {
        [0.0, 1.0, 0.0]
    } else {
        [0.0, 0.0, 1.0]
    };
    let b = cross3(u, e);
    let nb = norm3(&b);
    let b = [b[0] / nb, b[1] / nb, b[2] / nb];
    (b, cross3(u, b))
}
