#!/usr/bin/env python3
"""MuJoCo's accelerations on soft equalities, which the MJCF reader models as MuJoCo makes them.

Run by hand, like reference.py, with a Python that has MuJoCo:

    /some/venv/bin/pip install mujoco numpy
    /some/venv/bin/python tests/data/mjcf/soft_reference.py

It writes, next to itself:
  * panda_fingers.xml: ../robots/panda.xml with its fingers coupled as MuJoCo Menagerie's Panda
    ships them (`<joint joint1="finger_joint1" joint2="finger_joint2" solimp="0.95 0.99 0.001"
    solref="0.005 1"/>`);
  * soft_reference.json: for four_bar.xml (a `connect`, MuJoCo's default solref and solimp),
    coupled_pendulum.xml (a `joint` equality with an offset and a negative factor), soft_gripper.xml
    (hand-written: a class's direct solref and cubic impedance, a time constant MuJoCo raises to twice
    the step), panda_fingers.xml, welded_pendulum.xml (a `weld`, MuJoCo's defaults) and
    soft_weld.xml (hand-written: a weld with half its torque between a ball joint's body and a
    turned hinge's, a slider welded to the world), at 24 states each: q near the file's pose at residuals
    from 1e-4 to 1 (so the impedance is read on each piece of its curve), v and tau uniform in
    [-1, 1]: qacc = mj_forward with qfrc_applied = tau, and the equality rows' forces efc_force;
    and each file's run: 100 steps of MuJoCo's RK4 at the file's timestep from the sixth sample,
    its tau held (`<name>_rk4`: the end's qpos and qvel).
Joint limits and contacts are switched off (the scenes keep limits as data); the equalities are the
only constraints. qpos is MuJoCo's (`ref` at the file's pose); quaternions w x y z.
"""
import json
import os
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SEED = 2027
N = 24
SCALES = [1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 0.1, 0.5, 1.0]


def fingers():
    root = ET.parse(os.path.join(HERE, "../robots/panda.xml")).getroot()
    eq = ET.SubElement(root, "equality")
    ET.SubElement(eq, "joint", {"joint1": "panda_finger_joint1", "joint2": "panda_finger_joint2",
                                "solimp": "0.95 0.99 0.001", "solref": "0.005 1"})
    path = os.path.join(HERE, "panda_fingers.xml")
    with open(path, "w") as fh:
        fh.write("<!-- Written by soft_reference.py from ../robots/panda.xml: the fingers coupled as MuJoCo "
                 "Menagerie's Panda couples them. -->\n")
        fh.write(ET.tostring(root, encoding="unicode") + "\n")
    return path


def samples(path, rng):
    m = mujoco.MjModel.from_xml_path(path)
    m.jnt_limited[:] = 0
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    d = mujoco.MjData(m)
    out = []
    for k in range(N):
        scale = SCALES[k % len(SCALES)]
        q = m.qpos0.copy()
        for j in range(m.njnt):
            a = m.jnt_qposadr[j]
            if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL:
                w = np.array([1.0, 0, 0, 0]) + scale * rng.normal(size=4)
                q[a:a + 4] = w / np.linalg.norm(w)
            else:
                q[a] += scale * rng.uniform(-1, 1)
        v, tau = (rng.uniform(-1, 1, m.nv) for _ in range(2))
        d.qpos[:], d.qvel[:], d.qfrc_applied[:] = q, v, tau
        mujoco.mj_forward(m, d)
        assert d.nefc == d.ne, "only equality rows"
        out.append({"q": list(q), "v": list(v), "tau": list(tau), "qacc": list(d.qacc),
                    "efc_force": list(d.efc_force[:d.nefc]), "efc_pos": list(d.efc_pos[:d.nefc]),
                    "solver_niter": int(d.solver_niter[0])})
    return out


def run(path, start, steps):
    """`steps` RK4 steps of MuJoCo's own (`integrator="RK4"`, the file's timestep) from a sample's
    state under its qfrc_applied held: the end's qpos and qvel."""
    m = mujoco.MjModel.from_xml_path(path)
    m.jnt_limited[:] = 0
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    m.opt.integrator = int(mujoco.mjtIntegrator.mjINT_RK4)
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:], d.qfrc_applied[:] = start["q"], start["v"], start["tau"]
    for _ in range(steps):
        mujoco.mj_step(m, d)
    return {"start": 5, "steps": steps, "h": m.opt.timestep, "q": list(d.qpos), "v": list(d.qvel)}


def main():
    rng = np.random.default_rng(SEED)
    fingers()
    out = {"generator": f"soft_reference.py, MuJoCo {mujoco.__version__}"}
    for name in ["four_bar", "coupled_pendulum", "soft_gripper", "panda_fingers", "welded_pendulum", "soft_weld"]:
        out[name] = samples(os.path.join(HERE, name + ".xml"), rng)
        out[name + "_rk4"] = run(os.path.join(HERE, name + ".xml"), out[name][5], 100)
    with open(os.path.join(HERE, "soft_reference.json"), "w") as fh:
        json.dump(out, fh, indent=1)
        fh.write("\n")
    print("wrote", os.path.join(HERE, "soft_reference.json"))


if __name__ == "__main__":
    main()
