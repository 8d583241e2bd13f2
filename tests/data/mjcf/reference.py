#!/usr/bin/env python3
"""MuJoCo's own numbers for joints with armature, damping and springs, which the MJCF reader puts in the
dynamics as MuJoCo does.

Run by hand, like tests/data/robots/reference.py, with a Python that has MuJoCo:

    /some/venv/bin/pip install mujoco numpy
    /some/venv/bin/python tests/data/mjcf/reference.py

It writes, next to itself:
  * panda_damped.xml: ../robots/panda.xml with an armature and a damping on every joint, each
    joint's own (0.01 (k + 1) and 0.1 (k + 1) for the k-th), so that a value put on the wrong
    joint shows;
  * panda_springs.xml: the same with a spring on every joint, each its own stiffness 10 (k + 1),
    springref 0.1 k - 0.3 and ref 0.05 k (radians: the file's compiler says so);
  * panda_total.xml: the Panda with <compiler settotalmass="30">;
  * panda_gravcomp.xml: the Panda with gravcomp on some bodies, each its own fraction (1 on the
    links welded into its hand: one body's links share one), qfrc_gravcomp in MuJoCo's passive
    forces;
  * reference.json: for panda_damped.xml, ball_pendulum.xml, panda_springs.xml, springs.xml and
    panda_total.xml and panda_gravcomp.xml
    (hand-written: springs in degrees, from a class, on a slide; qpos is MuJoCo's, `ref` at the
    file's pose, so the tests convert it through the scene's MUJOCO layout), (a ball joint: armature and
    damping on each of its three freedoms), at 20 random states each (q, v, tau; quaternions
    w x y z, a ball's velocity and torque in the child's frame, as MuJoCo and the scenes have
    them): M (mj_fullM: armature on the diagonal), qacc = mj_forward with qfrc_applied = tau
    (damping: qfrc_passive = -damping v), and qfrc_inverse = mj_inverse at qacc = a (that is
    M a + bias + damping v).
Joint limits would be constraints in MuJoCo: the constraint solver is disabled (the scenes keep
limits as data). Gravity is the files' (MuJoCo's default 0 0 -9.81).
"""
import json
import os
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SEED = 2026
N = 20


def panda_variant(name, what, edit):
    """../robots/panda.xml changed by `edit(root)`, written next to this script as `name`."""
    root = ET.parse(os.path.join(HERE, "../robots/panda.xml")).getroot()
    edit(root)
    path = os.path.join(HERE, name)
    with open(path, "w") as fh:
        fh.write(f"<!-- Written by reference.py from ../robots/panda.xml: {what}. -->\n")
        fh.write(ET.tostring(root, encoding="unicode") + "\n")
    return path


def damped(root):
    for k, j in enumerate(root.iter("joint")):
        j.set("armature", repr(0.01 * (k + 1)))
        j.set("damping", repr(0.1 * (k + 1)))


def sprung(root):
    for k, j in enumerate(root.iter("joint")):
        j.set("stiffness", repr(10.0 * (k + 1)))
        j.set("springref", repr(0.1 * k - 0.3))
        j.set("ref", repr(0.05 * k))


def heavy(root):
    root.find("compiler").set("settotalmass", "30")


HELD = {"panda_link1": "1", "panda_link2": "1", "panda_link3": "0.5", "panda_link5": "0.25",
        "panda_link7": "1", "panda_link8": "1", "panda_hand": "1", "panda_hand_tcp": "1",
        "panda_leftfinger": "0.7"}


def held(root):
    for b in root.iter("body"):
        if b.get("name") in HELD:
            b.set("gravcomp", HELD[b.get("name")])


def samples(path, rng):
    m = mujoco.MjModel.from_xml_path(path)
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)
    d = mujoco.MjData(m)
    out = []
    for _ in range(N):
        q = np.zeros(m.nq)
        for j in range(m.njnt):
            a = m.jnt_qposadr[j]
            if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL:
                w = rng.normal(size=4)
                q[a:a + 4] = w / np.linalg.norm(w)
            else:
                q[a] = rng.uniform(-1.5, 1.5)
        v, tau, acc = (rng.uniform(-2, 2, m.nv) for _ in range(3))
        d.qpos[:], d.qvel[:], d.qfrc_applied[:] = q, v, tau
        mujoco.mj_forward(m, d)
        qacc = d.qacc.copy()
        mass = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, mass)
        d.qacc[:] = acc
        mujoco.mj_inverse(m, d)
        out.append({"q": list(q), "v": list(v), "tau": list(tau), "qacc": list(qacc), "a": list(acc),
                    "mass_matrix": [list(r) for r in mass], "inverse": list(d.qfrc_inverse)})
    return out


def main():
    rng = np.random.default_rng(SEED)
    panda_variant("panda_damped.xml", "every joint its own armature and damping", damped)
    out = {"generator": f"reference.py, MuJoCo {mujoco.__version__}",
           "panda_damped": samples(os.path.join(HERE, "panda_damped.xml"), rng),
           "ball_pendulum": samples(os.path.join(HERE, "ball_pendulum.xml"), rng)}
    panda_variant("panda_springs.xml", "every joint its own stiffness, springref and ref", sprung)
    out["panda_springs"] = samples(os.path.join(HERE, "panda_springs.xml"), rng)
    out["springs"] = samples(os.path.join(HERE, "springs.xml"), rng)
    panda_variant("panda_total.xml", "the compiler scales its masses and inertias to 30 kg in all", heavy)
    out["panda_total"] = samples(os.path.join(HERE, "panda_total.xml"), rng)
    panda_variant("panda_gravcomp.xml", "gravity compensation on some bodies, each its own fraction (the hand's "
                  "welded links all 1)", held)
    out["panda_gravcomp"] = samples(os.path.join(HERE, "panda_gravcomp.xml"), rng)
    with open(os.path.join(HERE, "reference.json"), "w") as fh:
        json.dump(out, fh, indent=1)
        fh.write("\n")
    print("wrote", os.path.join(HERE, "reference.json"))


if __name__ == "__main__":
    main()
