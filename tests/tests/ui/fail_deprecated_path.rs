// The modules renamed in 0.2 (`tree` → `relative`, `sparse` → `absolute`):
// a path through the old name warns, naming the new one (here denied, to
// show the warning as an error).
#![deny(deprecated)]

use joint_runtime::sparse::TermArray;
use joint_runtime::tree::TreeState;

fn main() {
    let _: Option<(TreeState<1, 1>, TermArray<0>)> = None;
}
