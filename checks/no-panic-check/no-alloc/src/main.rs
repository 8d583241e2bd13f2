//! A link-time proof that making a simulation or the kinematic analyses has no
//! panicking path, with `joint-runtime` built without `alloc` (its workspaces
//! then live inline, sized by the derive). `no-panic-check` proves every step,
//! `integrate` and analysis; this proves the `new` before them, which with
//! `alloc` boxes its workspaces (`Box::new`'s out-of-memory path counts as a
//! panic path there).
//!
//! ```text
//! cargo build --release --manifest-path checks/no-panic-check/no-alloc/Cargo.toml --features prove
//! ```
//!
//! The guard and the technique are `no-panic-check`'s (`../src/guard.rs`,
//! `../src/main.rs`). Options, springs and the integrator are arguments, so
//! every branch of `new` they select is inside the checked code: a spring
//! between bodies no joint joins under an implicit integrator, say, is refused
//! with an error here (its pattern needs `alloc`).

#[path = "../../src/guard.rs"]
#[macro_use]
mod guard;

/// Two scenes: a chain with the generated second-order terms, and the same
/// chain without them (the implicit integrators' difference terms).
mod scenes {
    use joint_runtime::analysis::{Analyses, AnalysisError};
    use joint_runtime::dynamics::{NoLoads, Simulation, SimulationOptions, SpringDamper};

    /// Four bars hanging on spherical joints, with `second_order`.
    #[derive(joint_runtime::Scene)]
    #[scene(coordinates = absolute, gravity = [0, 0, -9.81], second_order)]
    #[body(bar[4], mass = 1.0, inertia = [0.00125, 0.084, 0.084])]
    #[joint(pivot = spherical(ground, bar[0]), rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
    #[joint(ball[i in 1..4] = spherical(bar[i - 1], bar[i]), rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
    pub struct Chain;

    /// The same chain without `second_order`.
    #[derive(joint_runtime::Scene)]
    #[scene(coordinates = absolute, gravity = [0, 0, -9.81])]
    #[body(bar[4], mass = 1.0, inertia = [0.00125, 0.084, 0.084])]
    #[joint(pivot = spherical(ground, bar[0]), rho1 = [0, 0, 0], rho2 = [-0.5, 0, 0])]
    #[joint(ball[i in 1..4] = spherical(bar[i - 1], bar[i]), rho1 = [0.5, 0, 0], rho2 = [-0.5, 0, 0])]
    pub struct PlainChain;

    checked! {
        fn simulation_new<'a>(
            scene: &'a Chain,
            springs: &'a [SpringDamper],
            options: SimulationOptions,
        ) -> Result<Simulation<'a, Chain>, AnalysisError> {
            Simulation::new(scene, NoLoads, springs, options)
        }
        fn plain_simulation_new<'a>(
            scene: &'a PlainChain,
            springs: &'a [SpringDamper],
            options: SimulationOptions,
        ) -> Result<Simulation<'a, PlainChain>, AnalysisError> {
            Simulation::new(scene, NoLoads, springs, options)
        }
        fn analyses_new<'a>(scene: &'a Chain) -> Result<Analyses<'a, Chain, 4, 24, 12, 66>, AnalysisError> {
            Analyses::new(scene)
        }
    }
}

fn main() {
    println!("{} constructors linked without a panic path (joint-runtime without alloc)", scenes::keep());
}
