use joint_runtime::Scene;

// Each scene has one mistake in its contacts, and gets one message at it.

#[derive(Scene)]
#[scene(coordinates = relative)]
#[body(bar, mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
#[contact(tip = line(bar), at = [0.5, 0, 0])]
struct UnknownKind;

#[derive(Scene)]
#[scene(coordinates = relative)]
#[body(bar, mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
#[contact(tip = point(barr), at = [0.5, 0, 0])]
struct UnknownBody;

#[derive(Scene)]
#[scene(coordinates = relative)]
#[body(bar, mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[body(arm, mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
#[joint(elbow = revolute(bar, arm), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
#[contact(weld = frame(bar, arm))]
struct FrameBetweenBodies;

#[derive(Scene)]
#[scene(coordinates = relative)]
#[body(bar, mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
#[contact(tip = point(bar), axes = sideways)]
struct BadAxes;

#[derive(Scene)]
#[scene(coordinates = absolute)]
#[body(bar, mass = 1.0, inertia = [0.1, 0.1, 0.1])]
#[joint(pin = revolute(ground, bar), axis1 = [0, 1, 0], axis2 = [0, 1, 0], rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
#[contact(tip = point(bar))]
struct Absolute;

#[derive(Scene)]
#[scene(urdf = "../../data/robots/ur5.urdf")]
#[contact(weld = frame(tool1))]
struct UnknownLink;

fn main() {}
