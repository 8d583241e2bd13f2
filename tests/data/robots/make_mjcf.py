#!/usr/bin/env python3
"""The robots' MJCF files, written by MuJoCo's own compiler from the URDF files beside this script.

Run by hand, like reference.py, with a Python that has MuJoCo:

    python3 -m venv /some/venv
    /some/venv/bin/pip install mujoco numpy
    /some/venv/bin/python tests/data/robots/make_mjcf.py

It writes `<robot>.xml` next to itself: double_pendulum, ur5, panda, solo12 (fixed base) and
solo12_floating (a <freejoint/> on the root body: MuJoCo's counterpart of Pinocchio's
free-flyer root). The tests read them with `#[scene(mjcf = "..")]` and compare against the
same Pinocchio values (`<robot>.json`) as the URDF scenes: the MJCF path is checked against an
independent reference, not against the URDF reader.

What is done to each URDF (in memory; the URDF files are not touched):
  * <visual> and <collision> elements are removed (their package:// meshes are not here) and
    <mujoco><compiler discardvisual="true" fusestatic="false"/></mujoco> is added, so every
    URDF link is a MuJoCo body (the links on fixed joints are bodies without joints, which the
    reader welds to their parents, as it welds the URDF's fixed links);
  * every joint's damping is set to zero: the reader puts an MJCF's damping and armature in the
    dynamics, as MuJoCo does, and Pinocchio's reference (like its aba, rnea and crba) has none
    (the URDF's <dynamics damping> is data there); tests/data/mjcf/reference.py checks damping
    and armature against MuJoCo itself;
  * equality constraints are removed: MuJoCo turns panda's <mimic> into a joint equality,
    which the reader refuses (not read yet); Pinocchio's reference treats the mimic joint as
    an independent degree of freedom, and so does the file without it;
  * the model is compiled, and the MJCF written by MjSpec.to_xml(). That writer prints numbers
    with 6 significant digits (cos(pi/4) -> 0.707107), which would move the dynamics at the
    1e-6 level; so every body pos/quat, inertial pos/quat/mass/diaginertia and joint pos/axis
    is replaced by the compiled model's own value printed with 17 significant digits (MuJoCo
    has diagonalised each inertia: `quat` turns its principal axes). The file written is
    reloaded and checked to give the same model arrays (to 1e-15).
"""
import os
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
# (output name, URDF file, floating root?)
ROBOTS = [("double_pendulum", "double_pendulum.urdf", False), ("ur5", "ur5.urdf", False),
          ("panda", "panda.urdf", False), ("solo12", "solo12.urdf", False),
          ("solo12_floating", "solo12.urdf", True)]


def urdf_without_meshes(path):
    root = ET.parse(path).getroot()
    for link in root.iter("link"):
        for tag in ("visual", "collision"):
            for e in link.findall(tag):
                link.remove(e)
    ext = ET.SubElement(root, "mujoco")
    ET.SubElement(ext, "compiler", discardvisual="true", fusestatic="false")
    return ET.tostring(root, encoding="unicode")


def make(urdf, floating):
    spec = mujoco.MjSpec.from_string(urdf_without_meshes(urdf))
    spec.option.gravity = [0.0, 0.0, -9.81]
    for j in spec.joints:
        j.damping = np.zeros_like(np.asarray(j.damping, dtype=float)) if np.ndim(j.damping) else 0.0
    for e in list(spec.equalities):
        spec.delete(e)
    if floating:
        roots = [b for b in spec.worldbody.bodies]
        assert len(roots) == 1, [b.name for b in roots]
        roots[0].add_freejoint(name="root_joint")
    return spec, spec.compile()


def _fmt(a):
    return " ".join(repr(float(x)) for x in np.atleast_1d(a))


def full_precision_xml(xml, m):
    """The MJCF written by to_xml, its numbers replaced by the compiled model's values."""
    root = ET.fromstring(xml)
    bodies = list(root.find("worldbody").iter("body"))  # preorder = body ids 1 .. nbody-1
    assert len(bodies) == m.nbody - 1
    for i, b in enumerate(bodies, start=1):
        assert b.get("name") == m.body(i).name, (b.get("name"), m.body(i).name)
        b.set("pos", _fmt(m.body_pos[i]))
        b.set("quat", _fmt(m.body_quat[i]))
        inert = b.find("inertial")
        assert inert is not None
        for k in ("fullinertia", "diaginertia", "quat", "axisangle", "xyaxes", "zaxis", "euler"):
            inert.attrib.pop(k, None)
        inert.set("pos", _fmt(m.body_ipos[i]))
        inert.set("quat", _fmt(m.body_iquat[i]))
        inert.set("mass", _fmt(m.body_mass[i]))
        inert.set("diaginertia", _fmt(m.body_inertia[i]))
        for j in b.findall("joint"):
            if j.get("type") == "free":
                continue
            jid = m.joint(j.get("name")).id
            j.set("pos", _fmt(m.jnt_pos[jid]))
            j.set("axis", _fmt(m.jnt_axis[jid]))
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode") + "\n"


def main():
    for name, f, floating in ROBOTS:
        spec, m = make(os.path.join(HERE, f), floating)
        path = os.path.join(HERE, name + ".xml")
        with open(path, "w") as fh:
            fh.write(f"<!-- Written by make_mjcf.py with MuJoCo {mujoco.__version__} from {f}"
                     f"{' under a free joint' if floating else ''}. -->\n")
            fh.write(full_precision_xml(spec.to_xml(), m))
        m2 = mujoco.MjModel.from_xml_path(path)
        same = (m2.nq == m.nq and m2.nv == m.nv and m2.nbody == m.nbody and all(
            np.allclose(getattr(m2, a), getattr(m, a), rtol=1e-15, atol=1e-15)
            for a in ("body_pos", "body_quat", "body_ipos", "body_iquat", "body_mass",
                      "body_inertia", "jnt_pos", "jnt_axis")))
        assert same, name
        print(f"{name}: nq={m2.nq} nv={m2.nv} nbody={m2.nbody} njnt={m2.njnt} -> {path}")


if __name__ == "__main__":
    main()
