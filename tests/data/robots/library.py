#!/usr/bin/env python3
"""States, mass matrices and forward dynamics written by the robot libraries
themselves, for the tests of the scenes' `MUJOCO` and `PINOCCHIO` layouts.

Run by hand (like reference.py), with a Python that has MuJoCo and Pinocchio:

    python3 -m venv /some/venv
    /some/venv/bin/pip install mujoco pin numpy
    /some/venv/bin/python tests/data/robots/library.py

It writes `library.json` next to itself, one entry per (file, library):

  * library.xml and solo12_floating.xml in MuJoCo: random qpos (free and ball
    quaternions w x y z, uniform on the sphere; hinges in [-pi, pi]; slides in
    [-0.2, 0.2]), qvel and qfrc_applied normal; mj_forward gives qacc,
    mj_fullM the mass matrix. Constraints are switched off
    (mjDSBL_CONSTRAINT): random angles leave the files' ranges, where MuJoCo
    would add limit forces; nothing else in these files acts through them.
  * library.urdf in Pinocchio under a free-flyer root (buildModelFromUrdf with
    JointModelFreeFlyer): random q (quaternion x y z w, continuous joints as
    cos, sin), v and tau normal; aba gives a, crba the mass matrix (upper
    triangle mirrored).

Each sample stores the library's own vectors as they are; the tests convert
them, nothing here does. Each is checked before it is written: M a + bias = tau
(MuJoCo: M qacc + qfrc_bias = qfrc_applied; Pinocchio: rnea(q, v, a) = tau).
"""

import json
import math
import os

import mujoco
import numpy as np
import pinocchio as pin

HERE = os.path.dirname(os.path.abspath(__file__))
SEED = 2026
N_SAMPLES = 20


def unit_quaternion(rng):
    e = rng.standard_normal(4)
    return e / np.linalg.norm(e)


def mujoco_samples(name, rng):
    model = mujoco.MjModel.from_xml_path(os.path.join(HERE, name))
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    data = mujoco.MjData(model)
    out = []
    for _ in range(N_SAMPLES):
        for j in range(model.njnt):
            at, kind = model.jnt_qposadr[j], model.jnt_type[j]
            if kind == mujoco.mjtJoint.mjJNT_FREE:
                data.qpos[at:at + 3] = rng.uniform(-1, 1, 3)
                data.qpos[at + 3:at + 7] = unit_quaternion(rng)
            elif kind == mujoco.mjtJoint.mjJNT_BALL:
                data.qpos[at:at + 4] = unit_quaternion(rng)
            elif kind == mujoco.mjtJoint.mjJNT_HINGE:
                data.qpos[at] = rng.uniform(-math.pi, math.pi)
            else:
                data.qpos[at] = rng.uniform(-0.2, 0.2)
        data.qvel[:] = rng.standard_normal(model.nv)
        data.qfrc_applied[:] = rng.standard_normal(model.nv)
        mujoco.mj_forward(model, data)
        m = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, m)
        residual = m @ data.qacc + data.qfrc_bias - data.qfrc_passive - data.qfrc_applied
        assert np.abs(residual).max() < 1e-9 * max(1.0, np.abs(data.qfrc_applied).max()), residual
        out.append({
            "q": data.qpos.tolist(), "v": data.qvel.tolist(), "tau": data.qfrc_applied.tolist(),
            "mass_matrix": m.tolist(), "a": data.qacc.tolist(),
        })
    joints = [{"name": mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or "",
               "q_at": int(model.jnt_qposadr[j]), "v_at": int(model.jnt_dofadr[j])} for j in range(model.njnt)]
    return {"file": name, "library": "MuJoCo " + mujoco.__version__, "joints": joints, "samples": out}


def pinocchio_samples(name, rng):
    model = pin.buildModelFromUrdf(os.path.join(HERE, name), pin.JointModelFreeFlyer())
    data = model.createData()
    out = []
    for _ in range(N_SAMPLES):
        q = np.zeros(model.nq)
        for j in range(1, model.njoints):
            jm = model.joints[j]
            at, short = jm.idx_q, jm.shortname()
            if short == "JointModelFreeFlyer":
                q[at:at + 3] = rng.uniform(-1, 1, 3)
                q[at + 3:at + 7] = unit_quaternion(rng)
            elif short.startswith("JointModelRUB"):
                angle = rng.uniform(-math.pi, math.pi)
                q[at:at + 2] = [math.cos(angle), math.sin(angle)]
            elif short.startswith("JointModelP"):
                q[at] = rng.uniform(-0.2, 0.2)
            else:
                q[at] = rng.uniform(-math.pi, math.pi)
        v, tau = rng.standard_normal(model.nv), rng.standard_normal(model.nv)
        a = pin.aba(model, data, q, v, tau)
        m = pin.crba(model, data, q)
        m = np.triu(m) + np.triu(m, 1).T
        assert np.abs(pin.rnea(model, data, q, v, a) - tau).max() < 1e-9
        out.append({"q": q.tolist(), "v": v.tolist(), "tau": tau.tolist(), "mass_matrix": m.tolist(),
                    "a": np.asarray(a).tolist()})
    joints = [{"name": model.names[j], "q_at": int(model.joints[j].idx_q), "v_at": int(model.joints[j].idx_v)}
              for j in range(1, model.njoints)]
    return {"file": name, "library": "Pinocchio " + pin.__version__, "joints": joints, "samples": out}


def main():
    rng = np.random.default_rng(SEED)
    out = {
        "library_mujoco": mujoco_samples("library.xml", rng),
        "solo12_mujoco": mujoco_samples("solo12_floating.xml", rng),
        "library_pinocchio": pinocchio_samples("library.urdf", rng),
    }
    with open(os.path.join(HERE, "library.json"), "w") as f:
        json.dump(out, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
