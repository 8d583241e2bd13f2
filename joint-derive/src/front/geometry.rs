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

/// The eigenvalues of a symmetric 3 × 3 matrix, ascending (the
/// trigonometric closed form).
pub fn eigenvalues(a: &[[f64; 3]; 3]) -> [f64; 3] {
    let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    if off == 0.0 {
        let mut d = [a[0][0], a[1][1], a[2][2]];
        d.sort_by(f64::total_cmp);
        return d;
    }
    let q = (a[0][0] + a[1][1] + a[2][2]) / 3.0;
    let p2 = (a[0][0] - q).powi(2) + (a[1][1] - q).powi(2) + (a[2][2] - q).powi(2) + 2.0 * off;
    let p = (p2 / 6.0).sqrt();
    let b: [[f64; 3]; 3] =
        std::array::from_fn(|r| std::array::from_fn(|c| (a[r][c] - if r == c { q } else { 0.0 }) / p));
    let det = b[0][0] * (b[1][1] * b[2][2] - b[1][2] * b[2][1]) - b[0][1] * (b[1][0] * b[2][2] - b[1][2] * b[2][0])
        + b[0][2] * (b[1][0] * b[2][1] - b[1][1] * b[2][0]);
    let phi = (det / 2.0).clamp(-1.0, 1.0).acos() / 3.0;
    let high = q + 2.0 * p * phi.cos();
    let low = q + 2.0 * p * (phi + 2.0 * std::f64::consts::PI / 3.0).cos();
    [low, 3.0 * q - high - low, high]
}

/// Whether principal moments are a rigid body's: positive, each at most the
/// sum of the other two (to 1e-12 of their sum: a thin rod passes).
pub fn physical(moments: &[f64; 3]) -> bool {
    let sum = moments.iter().sum::<f64>();
    sum.is_finite() && moments.iter().all(|&m| m > 0.0 && m <= sum - m + 1e-12 * sum)
}
