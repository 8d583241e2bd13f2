//! A Cardan (Hooke, universal) joint between an input and an output shaft.
//!
//! The input shaft (B1) turns about its x axis; the output shaft (B2) is bent by
//! β about z and turns about its own x axis. The cross of the joint carries the
//! yoke axes `s` (fixed in B1) and `h` (fixed in B2). The program evaluates Φ, J
//! and γ at one configuration, checks Φ = 0 and J v = 0 at the closed-form output
//! angle and rate, and prints the operation counts.
//!
//! ```text
//! cargo run --release --example cardan
//! ```

use joint_runtime::nalgebra::{UnitQuaternion, Vector3};
use joint_runtime::{Joint, OmegaBody, TwoBodies};

/// Both yoke axes are constants, folded into the generated code; the joint
/// points are fields, read at run time.
#[derive(Joint)]
#[joint(universal, formulation = omega_body, s = [0, 1, 0], h = [0, 0, 1])]
struct Cardan<T> {
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

fn main() {
    let joint = Cardan { rho1: Vector3::new(0.5, 0.0, 0.0), rho2: Vector3::new(-0.5, 0.0, 0.0) };
    let (bend, phi1) = (30f64.to_radians(), 40f64.to_radians());
    // Output angle of an ideal Cardan joint: tan φ2 = tan φ1 / cos β.
    let phi2 = (phi1.tan() / bend.cos()).atan();
    let input = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), phi1);
    let output = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), bend)
        * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), phi2);
    // and its rate, the derivative of that: φ̇2 = φ̇1 cos²φ2 / (cos²φ1 cos β).
    let rate1 = 10.0;
    let rate2 = rate1 * phi2.cos().powi(2) / (phi1.cos().powi(2) * bend.cos());
    let centre = Vector3::new(0.5, 0.0, 0.0);
    let state = TwoBodies::new(
        OmegaBody::from_rotation(Vector3::zeros(), &input, Vector3::zeros(), Vector3::new(rate1, 0.0, 0.0)),
        OmegaBody::from_rotation(
            centre - output * Vector3::new(-0.5, 0.0, 0.0),
            &output,
            Vector3::zeros(),
            Vector3::new(rate2, 0.0, 0.0),
        ),
    );
    let e = joint.evaluate(&state);
    println!("Cardan joint, bend {:.0}°, input angle {:.0}°, output angle {:.4}°", 30.0, 40.0, phi2.to_degrees());
    println!("Φ (closes to rounding at the closed-form output angle) = {:.3e}", e.phi.transpose());
    println!("J (4 × 12: ṙ1, ω1', ṙ2, ω2') ={:.4}", e.jacobian);
    let v = joint_runtime::nalgebra::SVector::<f64, 12>::from_column_slice(&[
        0.0, 0.0, 0.0, rate1, 0.0, 0.0, 0.0, 0.0, 0.0, rate2, 0.0, 0.0,
    ]);
    println!("J v at the closed-form rates (zero to rounding) = {:.3e}", (e.jacobian * v).transpose());
    println!("γ = {:.6}", e.gamma.transpose());
    let ops = <Cardan<f64> as Joint<f64, 4, 12>>::OPS;
    println!(
        "operations: phi {}, jacobian {}, gamma {}, fused evaluate {}",
        ops.phi, ops.jacobian, ops.gamma, ops.evaluate
    );
}
