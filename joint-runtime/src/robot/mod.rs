//! What a robot's file says beyond its dynamics, as constants the derive
//! writes for `#[scene(urdf = "..")]` and `#[scene(mjcf = "..")]`: every
//! link's frame on its body (`Scene::LINKS`: end effectors, tool flanges,
//! the massless links a URDF uses as named frames, an MJCF's bodies and
//! sites) and every moving joint's limits (`Scene::LIMITS`), by the file's
//! names.
//!
//! A link's frame is given in its body's frame (origin at the body's
//! centre of mass): where it is and how it is turned. Its pose, velocity
//! and Jacobian at a state are then the body's, moved to it:
//! [`LinkFrame::pose`] and [`LinkFrame::velocity`] from the bodies'
//! [`SystemState`] (either coordinate choice converts to it),
//! [`LinkFrame::point`] for the point to give a point Jacobian, such as
//! [`Tree::point_jacobian`](crate::relative::Tree::point_jacobian).
//!
//! A relative-coordinate scene from a file also has `MUJOCO` (MJCF) or
//! `PINOCCHIO` (URDF), a [`StateLayout`]: states, accelerations and forces
//! to and from the library's vectors.

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

use crate::SystemState;

mod library;
pub use library::{Library, LibraryJoint, LibraryJointKind, StateError, StateLayout};

/// A link's frame on its body: `name` as in the file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkFrame {
    /// The link's name in the file.
    pub name: &'static str,
    /// The body it is part of (its index in the scene), `None` for the
    /// ground (the root link and the links fixed to it).
    pub body: Option<usize>,
    /// The link's axes in the body's frame, by columns (in the ground's
    /// frame for the ground).
    pub rotation: [[f64; 3]; 3],
    /// The link's origin from the body's centre of mass, in the body's
    /// frame (from the world's origin for the ground).
    pub origin: [f64; 3],
}

impl LinkFrame {
    /// The frame named `name` among `links` (a scene's `LINKS`).
    pub fn find<'l>(links: &'l [LinkFrame], name: &str) -> Option<&'l LinkFrame> {
        links.iter().find(|l| l.name == name)
    }

    /// A point given in the link's frame, in its body's frame (from the
    /// centre of mass): what a body point's Jacobian takes.
    pub fn point(&self, in_link: &Vector3<f64>) -> Vector3<f64> {
        self.turn() * in_link + Vector3::from(self.origin)
    }

    /// The link's orientation and origin in the world at the bodies' state.
    pub fn pose<const NB: usize>(&self, system: &SystemState<NB>) -> (UnitQuaternion<f64>, Vector3<f64>) {
        let turn = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&self.turn()));
        match self.body.and_then(|b| system.bodies.get(b)) {
            Some(b) => {
                let a = b.rotation();
                (a * turn, b.r + a * Vector3::from(self.origin))
            }
            None => (turn, Vector3::from(self.origin)),
        }
    }

    /// The link's angular velocity and its origin's velocity, both in the
    /// world's components, at the bodies' state: its body's `ω` and
    /// `ṙ + ω × (A origin)` (zero on the ground).
    pub fn velocity<const NB: usize>(&self, system: &SystemState<NB>) -> (Vector3<f64>, Vector3<f64>) {
        match self.body.and_then(|b| system.bodies.get(b)) {
            Some(b) => {
                let omega = b.omega_inertial();
                (omega, b.rdot + omega.cross(&(b.rotation_matrix() * Vector3::from(self.origin))))
            }
            None => (Vector3::zeros(), Vector3::zeros()),
        }
    }

    /// The link's axes in its body's frame (in the ground's for the
    /// ground) as a rotation matrix: `rotation`'s columns. A link's
    /// orientation in the world is its body's rotation times this
    /// ([`pose`](Self::pose) gives both).
    ///
    /// ```
    /// use joint_runtime::nalgebra::Matrix3;
    /// use joint_runtime::robot::LinkFrame;
    ///
    /// let quarter = LinkFrame { name: "tool0", body: Some(5), rotation: [[0., 1., 0.], [-1., 0., 0.], [0., 0., 1.]], origin: [0.; 3] };
    /// // The link's x axis is the body's y axis.
    /// assert_eq!(quarter.turn() * Matrix3::identity().column(0), Matrix3::identity().column(1));
    /// ```
    pub fn turn(&self) -> Matrix3<f64> {
        let [x, y, z] = self.rotation;
        Matrix3::from_columns(&[Vector3::from(x), Vector3::from(y), Vector3::from(z)])
    }
}

/// A shape a robot's file draws on a body (URDF `<visual>`, MJCF `<geom>`):
/// data for pictures ([`record`](crate::record) writes them into 3D runs);
/// the dynamics never use it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Visual {
    /// The body it is drawn on (its index in the scene), `None` for the
    /// ground.
    pub body: Option<usize>,
    /// The shape's axes in the body's frame, by columns (in the world's for
    /// the ground).
    pub rotation: [[f64; 3]; 3],
    /// The shape's origin from the body's centre of mass, in the body's
    /// frame (from the world's origin for the ground).
    pub origin: [f64; 3],
    /// What is drawn, in the shape's axes.
    pub shape: Shape,
    /// Red, green, blue and opacity in `[0, 1]`, where the file gives them
    /// (URDF `<material><color rgba>`, MJCF `rgba` or its material's); a
    /// mesh file's own colours otherwise.
    pub rgba: Option<[f64; 4]>,
}

/// A visual's shape, centred on its origin; lengths in metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// A box of these half sizes along its axes.
    Box([f64; 3]),
    /// A sphere of this radius.
    Sphere(f64),
    /// A cylinder along the shape's `z` axis: radius and half length.
    Cylinder(f64, f64),
    /// A capsule along the shape's `z` axis: radius and the half length of
    /// its cylinder (MJCF's `size`).
    Capsule(f64, f64),
    /// An ellipsoid of these semi-axes.
    Ellipsoid([f64; 3]),
    /// A plane's rectangle in the shape's `x`, `y`: half sizes (MJCF gives
    /// `0` for an infinite plane; a picture draws it finite).
    Plane([f64; 2]),
    /// A mesh file (STL, OBJ or Collada), scaled along its axes.
    Mesh {
        /// The file as found at compile time, absolute; the file's own
        /// name (a URDF's `package://` URI) where it was not found.
        file: &'static str,
        /// The file's `scale`.
        scale: [f64; 3],
    },
}

/// A moving joint's limits and friction as its file gives them (`None`
/// where it says nothing): data for a controller. Only an MJCF file's
/// `armature` and `damping` are also in the dynamics (in relative
/// coordinates, as MuJoCo has them); the rest the dynamics do not use.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointLimits {
    /// The joint's name in the file.
    pub name: &'static str,
    /// Lowest and highest coordinate (rad, or m for a slide), in the
    /// tree's coordinate (an MJCF joint's `ref` subtracted).
    pub range: Option<(f64, f64)>,
    /// Largest force or torque magnitude.
    pub effort: Option<f64>,
    /// Largest rate magnitude.
    pub velocity: Option<f64>,
    /// Viscous damping coefficient (URDF `<dynamics damping>`: data only;
    /// MJCF `damping`: in a relative-coordinate scene's dynamics too).
    pub damping: Option<f64>,
    /// Coulomb friction (URDF `<dynamics friction>`, MJCF `frictionloss`).
    pub friction: Option<f64>,
    /// Inertia added to the joint's own freedom (MJCF `armature`: in a
    /// relative-coordinate scene's dynamics too).
    pub armature: Option<f64>,
}

/// What a robot's file asks of the step (MJCF's `<option timestep
/// integrator>`; a URDF has none): data, the scene's `OPTIONS`. The step is
/// the caller's here: MuJoCo's `RK4` is [`TreeSimulation::step`]'s, its
/// `implicit` and `implicitfast` (damping, and for `implicit` the forces'
/// derivatives, in the Newton matrix) what
/// [`TreeSimulation::implicit_step_with`] does with the exact derivatives,
/// its `Euler` (semi-implicit, damping implicit) a first-order step that
/// `implicit_step_with` with zero gains covers.
///
/// [`TreeSimulation::step`]: crate::relative::TreeSimulation::step
/// [`TreeSimulation::implicit_step_with`]: crate::relative::TreeSimulation::implicit_step_with
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FileOptions {
    /// The file's step (s): an MJCF file's `timestep`, MuJoCo's default
    /// 0.002 s where it omits it; `None` for a URDF (which has none).
    pub timestep: Option<f64>,
    /// The file's integrator: an MJCF file's `integrator`, MuJoCo's default
    /// `Euler` where it omits it; `None` for a URDF.
    pub integrator: Option<FileIntegrator>,
}

/// MuJoCo's integrators, by its names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileIntegrator {
    /// `Euler`: semi-implicit Euler, damping implicit.
    Euler,
    /// `RK4`: the classical Runge–Kutta method.
    Rk4,
    /// `implicit`: implicit in the velocity, every force's derivative.
    Implicit,
    /// `implicitfast`: the same without the Coriolis terms' derivatives.
    ImplicitFast,
}
