// One mistake in the declaration gives one error, even where the struct is used
// as a joint afterwards: the derive emits a stub impl with the right shape.
use joint_runtime::nalgebra::{Vector3, Vector4};
use joint_runtime::{Joint, OmegaBody, TwoBodies};

#[derive(Joint)]
#[joint(universal, formulation = omega_body)]
struct Cardan<T> {
    s: Vector3<T>,
    h: Vector4<T>,
    rho1: Vector3<T>,
    rho2: Vector3<T>,
}

fn use_it(j: &Cardan<f64>, state: &TwoBodies<OmegaBody<f64>>) -> f64 {
    j.evaluate(state).phi[3] + <Cardan<f64> as Joint<f64, 4, 12>>::ROWS as f64
}

fn main() {
    let _ = use_it;
}
