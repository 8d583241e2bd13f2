use joint_runtime::nalgebra::Vector3;
use joint_runtime::{AxisFrame, Ramp, Scene};

#[derive(Scene)]
#[scene(coordinates = absolute, gravity = [0, 0, -9.81])]
#[body(link, mass = 1.0, inertia = [0.1, 0.1, 0.01])]
#[body(bob, mass = mass, inertia = moments)]
#[joint(hinge = revolute(ground, link), axis1 = axis, axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [0, 0, 0.5])]
#[joint(ball = spherical(link, bob), rho1 = [0, 0, -0.5], rho2 = [0.007 - 0.00092, 0, -1.0 / 5.0 + 0.4])]
#[joint(motor = rotational_driver(ground, link), axis1 = [0, 1, 0], axis2 = [0, 1, 0], theta = drive)]
struct Driven<F> {
    axis: AxisFrame<f64>,
    mass: f64,
    moments: Vector3<f64>,
    drive: F,
}

fn main() {
    let scene = Driven {
        axis: AxisFrame::new(Vector3::y()).unwrap(),
        mass: 0.5,
        moments: Vector3::new(0.01, 0.01, 0.01),
        drive: Ramp { start: 0.0, rate: 1.0 },
    };
    assert_eq!(<Driven<Ramp> as Scene<2, 12, 9>>::BODIES, ["link", "bob"]);
    // Bodies by name and the sizes, without the trait's parameters.
    assert_eq!((Driven::<Ramp>::LINK, Driven::<Ramp>::BOB), (0, 1));
    assert_eq!((Driven::<Ramp>::NB, Driven::<Ramp>::NV, Driven::<Ramp>::ROWS), (2, 12, 9));
    assert_eq!(Driven::<Ramp>::BLOCKS[1].name, "ball");
    assert_eq!(scene.inertias()[1].mass, 0.5);
    // Arithmetic in the attribute is folded as Rust folds it.
    let mut points = Vec::new();
    scene.joint_points(&mut |p| points.push(p));
    assert_eq!(points[3].point, Vector3::new(0.007 - 0.00092, 0.0, -1.0 / 5.0 + 0.4));
}
