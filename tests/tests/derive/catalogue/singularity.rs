//! The generated measures against closed forms written with nalgebra.

use super::user_rows::{UniOB, UniOI, UniR2};
use super::*;

/// `(A1, A2, d)` of an absolute state (unit p) or a relative one (`A1 = I`).
fn frames(c: &Coords<f64>, p: &Params<f64>, relative: bool) -> (Matrix3<f64>, Matrix3<f64>, Vector3<f64>) {
    if relative {
        (Matrix3::identity(), rotation_matrix(&c.p(0)), c.x(0))
    } else {
        let (a1, a2) = (rotation_matrix(&c.p(0)), rotation_matrix(&c.p(1)));
        (a1, a2, c.x(1) + a2 * p.rho2() - c.x(0) - a1 * p.rho1())
    }
}

fn sine_sq(a: Vector3<f64>, b: Vector3<f64>) -> f64 {
    a.cross(&b).norm_squared() / (a.norm_squared() * b.norm_squared())
}

fn check(what: &str, got: f64, want: f64) -> Res {
    prop_assert!(
        (got - want).abs() <= 1e-12 * (1.0 + want.abs()) && (-1e-12..=1.0 + 1e-12).contains(&got),
        "{what}: measure {got:e}, closed form {want:e}"
    );
    Ok(())
}

/// A joint and a state, probed for a `Singularity` impl at run time (autoref
/// specialisation), so that a joint the README says has a measure but whose impl
/// is missing fails a test instead of the whole file's compilation.
#[allow(dead_code)] // Read only through `HasMeasure`, unused while no probed joint has a measure.
struct Probe<'a, J, S, const R: usize, const C: usize>(&'a J, &'a S);

#[allow(dead_code)] // As `Probe`.
trait HasMeasure {
    fn measure_of(&self) -> Option<f64>;
}
impl<J: Singularity<f64, R, C, State = S>, S, const R: usize, const C: usize> HasMeasure for Probe<'_, J, S, R, C> {
    fn measure_of(&self) -> Option<f64> {
        Some(self.0.singularity(self.1))
    }
}

proptest! {
    #![proptest_config(config())]
    /// universal: sin² of the angle between A1 s and A2 h.
    #[test]
    fn universal_is_sine_squared(k in case(true)) {
        let (s, h) = (k.p.s(), k.p.h());
        for (rel, got) in [
            (false, UniOI::new(&k.p).singularity(&OmegaInertial::build(&k.c, k.t0))),
            (false, UniOB::new(&k.p).singularity(&OmegaBodyF::build(&k.c, k.t0))),
            (true, UniR2::new(&k.p).singularity(&RelB2::build(&k.c, k.t0))),
        ] {
            let (a1, a2, _) = frames(&k.c, &k.p, rel);
            check("universal", got, sine_sq(a1 * s, a2 * h))?;
        }
    }

    /// revolute (and the other `f, g, h` joints): cos² of the angle between A2 h and A1 (f × g).
    #[test]
    fn axis_alignment_is_cosine_squared(k in case(true)) {
        let (f, g, h) = (k.p.f(), k.p.g(), k.p.h());
        let cos_sq = |a1: Matrix3<f64>, a2: Matrix3<f64>| {
            let (n, h) = (a1 * f.cross(&g), a2 * h);
            let c = n.dot(&h);
            c * c / (n.norm_squared() * h.norm_squared())
        };
        let (a1, a2, _) = frames(&k.c, &k.p, false);
        let want = cos_sq(a1, a2);
        let s = OmegaBodyF::build(&k.c, k.t0);
        check("revolute omega_body", revolute::JointOb::new(&k.p).singularity(&s), want)?;
        check("cylindrical omega_body", cylindrical::JointOb::new(&k.p).singularity(&s), want)?;
        check("parallel omega_body", parallel::JointOb::new(&k.p).singularity(&s), want)?;
        let (a1, a2, _) = frames(&k.c, &k.p, true);
        check("revolute relative_b1", revolute::JointR1::new(&k.p).singularity(&RelB1::build(&k.c, k.t0)), cos_sq(a1, a2))?;
        // planar: the same measure, `n` playing no part.
        let (a1, a2, _) = frames(&k.c, &k.p, false);
        check("planar omega_inertial", planar::JointOi::new(&k.p).singularity(&OmegaInertial::build(&k.c, k.t0)), cos_sq(a1, a2))?;
    }

    /// translational, fixed: det[A1f × A2h, A1g × A2h, A1f × A2k]² / (|f|⁴ |g|² |h|⁴ |k|²).
    #[test]
    fn rotation_lock_is_normalised_determinant(k in case(true)) {
        let (f, g, h, kk) = (k.p.f(), k.p.g(), k.p.h(), k.p.k());
        let (a1, a2, _) = frames(&k.c, &k.p, false);
        let (f1, g1, h2, k2) = (a1 * f, a1 * g, a2 * h, a2 * kk);
        let det = f1.cross(&h2).dot(&g1.cross(&h2).cross(&f1.cross(&k2)));
        let want = det * det / (f.norm_squared().powi(2) * g.norm_squared() * h.norm_squared().powi(2) * kk.norm_squared());
        let s = OmegaInertial::build(&k.c, k.t0);
        check("translational", translational::JointOi::new(&k.p).singularity(&s), want)?;
        check("fixed", fixed::JointOi::new(&k.p).singularity(&s), want)?;
    }

    /// distance: |d|² / L² (README); see [`measure_of`] for how a missing impl fails.
    #[test]
    fn distance_is_separation_over_length(k in case(true)) {
        let mut p = k.p;
        p.0[24] = 0.5 + p.0[24].abs();
        let (_, _, d) = frames(&k.c, &p, false);
        let got = Probe::<_, _, 1, 12>(&distance::JointOb::new(&p), &OmegaBodyF::build(&k.c, k.t0)).measure_of();
        let want = d.norm_squared() / (p.sc() * p.sc());
        prop_assert!(got.is_some(), "distance (omega_body) has no `Singularity` impl; the README promises |d|²/L² = {want:e}");
        let got = got.unwrap_or(f64::NAN);
        prop_assert!((got - want).abs() <= 1e-12 * (1.0 + want), "distance: {got:e} vs {want:e}");
        let got = Probe::<_, _, 1, 6>(&distance::JointR1::new(&p), &RelB1::build(&k.c, k.t0)).measure_of().unwrap_or(f64::NAN);
        let want = k.c.x(0).norm_squared() / (p.sc() * p.sc());
        prop_assert!((got - want).abs() <= 1e-12 * (1.0 + want), "distance relative_b1: {got:e} vs {want:e}");
    }
}

/// The nominal geometry gives 1.
#[test]
fn nominal_geometry_gives_one() {
    let mut p: Params<f64> = Flat([0.0; 25]);
    // f = x, g = y (B1), h = z, k = y (B2), s = y: orthonormal, nominal.
    p.set(0, &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0]);
    p.set(15, &[0.0, 1.0, 0.0]);
    p.0[24] = 2.0;
    let mut c: Coords<f64> = Flat([0.0; 34]);
    c.0[3] = 1.0;
    c.0[BODY + 3] = 1.0;
    c.set(BODY, &[2.0, 0.0, 0.0]);
    let s = OmegaInertial::build(&c, 0.0);
    let one = |x: f64| (x - 1.0).abs() < 1e-15;
    assert!(one(revolute::JointOi::new(&p).singularity(&s)));
    assert!(one(translational::JointOi::new(&p).singularity(&s)));
    assert!(one(fixed::JointOi::new(&p).singularity(&s)));
    assert!(one(planar::JointOi::new(&p).singularity(&s)));
    assert!(one(perpendicular::JointOi::new(&p).singularity(&s)));
    assert!(Probe::<_, _, 1, 12>(&distance::JointOi::new(&p), &s).measure_of().is_none_or(one), "distance at |d| = L");
    let mut u = p;
    u.set(6, &[0.0, 0.0, 1.0]);
    assert!(one(UniOI::new(&u).singularity(&s)));
    assert!(!<UniOI<f64> as Singularity<f64, 4, 12>>::ZERO_WHEN.is_empty());
}

/// A Cardan joint (README): yokes `s = y` on shaft 1, `h = z` on shaft 2, both
/// shafts along x, joint point between them. Shaft 1 turned by ψ1 about x, shaft 2
/// bent by β about z and turned by ψ2 about its own axis.
fn cardan(beta: f64, psi1: f64, psi2: f64) -> (UniOB<f64>, TwoBodies<OmegaBody<f64>>) {
    let joint = UniOB {
        s: Vector3::y(),
        h: Vector3::z(),
        rho1: Vector3::new(0.5, 0.0, 0.0),
        rho2: Vector3::new(-0.5, 0.0, 0.0),
    };
    let q1 = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), psi1);
    let q2 = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), beta)
        * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), psi2);
    let r2 = Vector3::new(0.5, 0.0, 0.0) - q2 * joint.rho2;
    let b1 = OmegaBody::from_rotation(Vector3::zeros(), &q1, Vector3::zeros(), Vector3::zeros());
    let b2 = OmegaBody::from_rotation(r2, &q2, Vector3::zeros(), Vector3::zeros());
    (joint, TwoBodies::new(b1, b2))
}

/// On an assembled Cardan (Φ = 0: tan ψ2 = tan ψ1 / cos β) the yokes stay
/// perpendicular whatever the bend, so sin² of their angle is 1 even as β → 90°:
/// the measure sees the rank of this joint's own rows (which a 90° bend does not
/// reduce; J keeps its smallest singular value), not the mechanism's transmission
/// singularity. The README's "(zero at a 90° shaft bend)" does not hold for an
/// assembled joint (reported).
#[test]
fn assembled_cardan_bend_keeps_measure_one() {
    for beta_deg in [0.0f64, 30.0, 80.0, 89.0, 89.9] {
        for psi1 in [0.0f64, 0.4, 1.2, 2.5] {
            let beta = beta_deg.to_radians();
            let psi2 = f64::atan2(psi1.sin(), psi1.cos() * beta.cos());
            let (joint, state) = cardan(beta, psi1, psi2);
            let phi = joint.phi(&state);
            assert!(phi.norm() < 1e-14, "β = {beta_deg}°, ψ1 = {psi1}: Φ = {phi:?}");
            let m = joint.singularity(&state);
            assert!((m - 1.0).abs() < 1e-14, "β = {beta_deg}°, ψ1 = {psi1}: measure {m}");
            let sv = joint.jacobian(&state).svd(false, false).singular_values;
            assert!(sv.min() > 0.3, "β = {beta_deg}°: smallest singular value of J {}", sv.min());
        }
    }
}

/// Where the measure does go to 0: the yokes turned towards each other. Shaft 2
/// turned by β about the shaft axis from the straight, assembled Cardan, so that
/// `A2 h = (0, −sin β, cos β)` and the angle between the yokes is 90° − β:
/// measure = sin²(90° − β) = cos²β, and Φ's dot-1 row = −sin β.
#[test]
fn yokes_turned_towards_each_other_give_cos_squared() {
    let mut last = 1.0;
    for beta_deg in [0.0f64, 45.0, 80.0, 89.0, 89.9, 89.99] {
        let beta = beta_deg.to_radians();
        let (joint, state) = cardan(0.0, 0.0, beta);
        let m = joint.singularity(&state);
        let want = beta.cos().powi(2);
        assert!((m - want).abs() <= 1e-15 + 1e-12 * want, "β = {beta_deg}°: measure {m:e}, cos²β = {want:e}");
        assert!(m <= last, "not decreasing at β = {beta_deg}°");
        last = m;
        assert!((joint.phi(&state)[3] + beta.sin()).abs() < 1e-15);
    }
    assert!(last < 1e-7);
}

/// revolute: B2 tilted by β about an axis perpendicular to the joint axis (h = z
/// in B2, f = x, g = y in B1): measure = cos²β → 0 as h falls into the f, g plane.
#[test]
fn revolute_tilt_gives_cos_squared() {
    let mut p: Params<f64> = Flat([0.0; 25]);
    p.set(0, &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
    for beta_deg in [0.0f64, 80.0, 89.0, 89.9] {
        let beta = beta_deg.to_radians();
        let q2 = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), beta);
        let b1 =
            OmegaBody::from_rotation(Vector3::zeros(), &UnitQuaternion::identity(), Vector3::zeros(), Vector3::zeros());
        let b2 = OmegaBody::from_rotation(Vector3::zeros(), &q2, Vector3::zeros(), Vector3::zeros());
        let m = revolute::JointOb::new(&p).singularity(&TwoBodies::new(b1, b2));
        let want = beta.cos().powi(2);
        assert!((m - want).abs() <= 1e-15 + 1e-12 * want, "β = {beta_deg}°: measure {m:e}, cos²β = {want:e}");
    }
}
