#!/usr/bin/env python3
"""MuJoCo's own numbers for the corpus of public robot files (`corpus/<folder>/<file>.xml`, byte
copies of MuJoCo Menagerie's files; `LICENSES.md` says where each came from), for
`tests/tests/runtime/corpus.rs`.

Run by hand, like ../reference.py and ../../mjcf/reference.py, with a Python that has MuJoCo 4.0:

    python3 -m venv /some/venv
    /some/venv/bin/pip install mujoco==4.0.0 numpy
    /some/venv/bin/python tests/data/robots/corpus/reference.py

It writes `reference.json` next to itself: for every file, its SHA-256, MuJoCo's joints in
MuJoCo's order (name, "" where the file gives none; body, type, qpos and dof addresses) and N
random states, each with

  * `q`, `v`, `tau`: qpos, qvel and qfrc_applied, MuJoCo's own vectors (quaternions w x y z; a
    free joint's qvel its origin's velocity in the world's axes, then its angular velocity in the
    body's): hinges and slides uniform in their ranges ([-pi, pi] and [-0.2, 0.2] where a joint
    has none), a free joint's position in [-1, 1]^3 and its quaternion uniform on the sphere,
    qvel and qfrc_applied normal;
  * `mass_matrix`: mj_fullM's M (armature on the diagonal), its lower triangle, row i its
    first i + 1 entries (M is checked symmetric before);
  * `qacc`: mj_forward's accelerations under qfrc_applied = tau;
  * `a`, `inverse`: a random acceleration (normal) and mj_inverse's qfrc_inverse there, that is
    M a + qfrc_bias - qfrc_passive.

Before a sample is written, mj_inverse at qacc = mj_forward's qacc must give tau back (to 1e-9 of
its size), which checks that the forward and inverse dynamics here are one model.

What is switched off, and why. The scenes model a tree's rigid-body dynamics with what the MJCF
reader puts in it (ARCHITECTURE.md, joint-derive/src/front/mjcf.rs): gravity, armature, joint
damping, joint springs (stiffness, springref, ref) and gravity compensation (gravcomp), all of
which stay on here (MuJoCo's qfrc_passive). Everything else in MuJoCo's forward dynamics is
switched off through `opt.disableflags`, each bit named:

  * mjDSBL_CONTACT: contacts (the scenes have no geometry that collides; geoms are pictures);
  * mjDSBL_CONSTRAINT, with mjDSBL_LIMIT, mjDSBL_EQUALITY and mjDSBL_FRICTIONLOSS named too:
    the constraint solver, so no joint-limit forces (random states leave no range, but a limit's
    margin could still act; the scenes keep ranges as data), no equality (none in these files)
    and no dry friction (`frictionloss` is a constraint in MuJoCo; the scenes keep it as data);
  * mjDSBL_ACTUATION: actuator forces (actuators are not read; the files' position servos would
    push with kp (ctrl - q) even at ctrl = 0).

Nothing else is changed: not the files, not the options. Several files ask for
`integrator="implicitfast"`, which acts in mj_step only: mj_forward's qacc and mj_inverse's
qfrc_inverse are the continuous-time dynamics (mjENBL_INVDISCRETE is off, MuJoCo's default). Mesh
files (`<mesh file>`) and texture images are not in the corpus (only the XML text is), and
MuJoCo's compiler needs them: the script gives every mesh a small tetrahedron as its vertices and
every file texture a built-in checker instead, through MjSpec before compiling (and checks that
stand-ins 25 times larger change no body's mass, centre or inertia). They are pictures
and collision shapes: every body that moves has its own `<inertial>` in these files (the reader
refuses a moving body whose mass would come from its geoms), so no mass or inertia comes from
them, and with contacts off no geom acts.
"""

import hashlib
import json
import math
import os

import mujoco
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SEED = 2026
N = 10

# (key, path under this folder): fixed arms and a hand, then floating robots.
FILES = [
    ("panda", "franka_emika_panda/panda_nohand.xml"),
    ("ur5e", "universal_robots_ur5e/ur5e.xml"),
    ("gen3", "kinova_gen3/gen3.xml"),
    ("iiwa14", "kuka_iiwa_14/iiwa14.xml"),
    ("sawyer", "rethink_robotics_sawyer/sawyer.xml"),
    ("xarm7", "ufactory_xarm7/xarm7_nohand.xml"),
    ("z1", "unitree_z1/z1.xml"),
    ("shadow_hand", "shadow_hand/right_hand.xml"),
    ("go1", "unitree_go1/go1.xml"),
    ("go2", "unitree_go2/go2.xml"),
    ("a1", "unitree_a1/a1.xml"),
    ("anymal_c", "anybotics_anymal_c/anymal_c.xml"),
    ("spot", "boston_dynamics_spot/spot.xml"),
    ("barkour_v0", "google_barkour_v0/barkour_v0.xml"),
    ("h1", "unitree_h1/h1.xml"),
    ("g1", "unitree_g1/g1.xml"),
    ("t1", "booster_t1/t1.xml"),
    ("tiago", "pal_tiago/tiago.xml"),
]

DISABLED = ("mjDSBL_CONTACT", "mjDSBL_CONSTRAINT", "mjDSBL_LIMIT", "mjDSBL_EQUALITY", "mjDSBL_FRICTIONLOSS",
            "mjDSBL_ACTUATION")

# A tetrahedron `size` across: a mesh's stand-in, only so that MuJoCo compiles without the file.
def tetrahedron(size):
    return [0.0, 0.0, 0.0, size, 0.0, 0.0, 0.0, size, 0.0, 0.0, 0.0, size]

TYPES = {int(mujoco.mjtJoint.mjJNT_FREE): "free", int(mujoco.mjtJoint.mjJNT_BALL): "ball",
         int(mujoco.mjtJoint.mjJNT_SLIDE): "slide", int(mujoco.mjtJoint.mjJNT_HINGE): "hinge"}


def load(path, size=0.02):
    """The file compiled by MuJoCo with stand-ins for its mesh (tetrahedra `size` across) and
    texture files, and the switches of the docstring off."""
    spec = mujoco.MjSpec.from_file(path)
    for mesh in spec.meshes:
        mesh.file = ""
        mesh.uservert = tetrahedron(size)
    for texture in spec.textures:
        if texture.file:
            texture.file = ""
            texture.builtin = mujoco.mjtBuiltin.mjBUILTIN_CHECKER
            texture.width = texture.height = 8
    model = spec.compile()
    for bit in DISABLED:
        model.opt.disableflags |= int(getattr(mujoco.mjtDisableBit, bit))
    return model


def unit_quaternion(rng):
    e = rng.standard_normal(4)
    return e / np.linalg.norm(e)


def random_qpos(model, rng):
    """A random qpos: every coordinate inside its joint's range (the file's, in radians or metres
    as MuJoCo compiled it), quaternions of unit length."""
    q = np.zeros(model.nq)
    for j in range(model.njnt):
        at, kind = model.jnt_qposadr[j], model.jnt_type[j]
        if kind == mujoco.mjtJoint.mjJNT_FREE:
            q[at:at + 3] = rng.uniform(-1, 1, 3)
            q[at + 3:at + 7] = unit_quaternion(rng)
        elif kind == mujoco.mjtJoint.mjJNT_BALL:
            q[at:at + 4] = unit_quaternion(rng)
        elif model.jnt_limited[j]:
            q[at] = rng.uniform(*model.jnt_range[j])
        else:
            half = math.pi if kind == mujoco.mjtJoint.mjJNT_HINGE else 0.2
            q[at] = rng.uniform(-half, half)
    return q


def sample(model, data, rng):
    """One state's numbers, checked: M symmetric, mj_inverse(mj_forward(tau)) = tau."""
    data.qpos[:] = random_qpos(model, rng)
    data.qvel[:] = rng.standard_normal(model.nv)
    data.qfrc_applied[:] = rng.standard_normal(model.nv)
    mujoco.mj_forward(model, data)
    qacc = data.qacc.copy()
    m = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, m)
    assert np.array_equal(m, m.T), "M is symmetric"
    mujoco.mj_inverse(model, data)
    back = data.qfrc_inverse - data.qfrc_applied
    assert np.abs(back).max() < 1e-9 * max(1.0, np.abs(data.qfrc_applied).max()), back
    a = rng.standard_normal(model.nv)
    data.qacc[:] = a
    mujoco.mj_inverse(model, data)
    expected = m @ a + data.qfrc_bias - data.qfrc_passive
    assert np.abs(data.qfrc_inverse - expected).max() < 1e-9 * max(1.0, np.abs(expected).max())
    return {"q": data.qpos.tolist(), "v": data.qvel.tolist(), "tau": data.qfrc_applied.tolist(),
            "mass_matrix": [m[i, :i + 1].tolist() for i in range(model.nv)], "qacc": qacc.tolist(),
            "a": a.tolist(), "inverse": data.qfrc_inverse.tolist()}


def robot(path, rng):
    full = os.path.join(HERE, path)
    model = load(full)
    # No body's mass, centre or inertia comes from a mesh: stand-ins 25 times larger change none.
    other = load(full, 0.5)
    for field in ("body_mass", "body_inertia", "body_ipos", "body_iquat"):
        assert np.array_equal(getattr(model, field), getattr(other, field)), (path, field)
    data = mujoco.MjData(model)
    joints = [{"name": mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or "",
               "body": mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, model.jnt_bodyid[j]),
               "type": TYPES[int(model.jnt_type[j])], "q_at": int(model.jnt_qposadr[j]),
               "v_at": int(model.jnt_dofadr[j])} for j in range(model.njnt)]
    with open(full, "rb") as fh:
        digest = hashlib.sha256(fh.read()).hexdigest()
    return {"file": path, "sha256": digest, "nq": model.nq, "nv": model.nv, "joints": joints,
            "samples": [sample(model, data, rng) for _ in range(N)]}


def main():
    rng = np.random.default_rng(SEED)
    out = {"generator": f"reference.py, MuJoCo {mujoco.__version__}", "disabled": list(DISABLED)}
    for key, path in FILES:
        out[key] = robot(path, rng)
        print(f"{key}: {path}, nq {out[key]['nq']}, nv {out[key]['nv']}")
    with open(os.path.join(HERE, "reference.json"), "w") as fh:
        # Compact, one robot a line; floats as Python's repr, which reads back to the same double.
        fh.write("{\n")
        fh.write(",\n".join(f"{json.dumps(k)}:{json.dumps(v, separators=(',', ':'))}" for k, v in out.items()))
        fh.write("\n}\n")
    print("wrote", os.path.join(HERE, "reference.json"))


if __name__ == "__main__":
    main()
