// `second_order` on a tree whose derivatives the derive would write out
// past its limit changes nothing (the runtime's recursion gives them): the
// derive says so at the option, as a warning (here denied, to show it).
#![deny(deprecated)]

use joint_runtime::Scene;

#[derive(Scene)]
#[scene(urdf = "../../data/robots/panda.urdf", mimic = independent, second_order)]
struct Panda;

fn main() {}
