#!/usr/bin/env python3
"""Independent reference values for the robots read from URDF files.

Run by hand (like the conformance vectors), with a Python that has Pinocchio:

    python3 -m venv /some/venv
    /some/venv/bin/pip install pin numpy
    /some/venv/bin/python tests/data/robots/reference.py

It reads the URDF files next to itself and writes `<robot>.json` next to
itself: double_pendulum, ur5, panda, solo12 (fixed base) and solo12_floating
(the same URDF under a free-flyer root joint).

Every model is `pinocchio.buildModelFromUrdf(path)` (fixed base), or
`pinocchio.buildModelFromUrdf(path, pinocchio.JointModelFreeFlyer())`, with
Pinocchio's default gravity (0, 0, -9.81). URDF <dynamics> damping is stored
in model.damping but crba/rnea/aba do not use it; <transmission> is ignored,
and so, with buildModelFromUrdf's default mimic=False, is <mimic>: a mimic
joint is an independent degree of freedom here.

Each value written is checked before it is written:
  * the point Jacobian against central finite differences of the point's world
    position along each velocity direction (pinocchio.integrate), to 1e-6;
  * rnea(q, v, aba(q, v, tau)) == tau and M == M^T.
"""

import hashlib
import json
import math
import os
import sys
import time

import numpy as np
import pinocchio as pin
import xml.etree.ElementTree as ET

HERE = os.path.dirname(os.path.abspath(__file__))
SEED = 2026
N_SAMPLES = 100
POINT = [0.1, 0.05, 0.02]
FD_EPS = 1e-6
FD_TOL = 1e-6
MOTION_H = 1e-4
MOTION_T = 1.0

# (output name, URDF file, floating root?, link carrying the point)
ROBOTS = [
    ("double_pendulum", "double_pendulum.urdf", False, "link2"),
    ("ur5", "ur5.urdf", False, "tool0"),
    ("panda", "panda.urdf", False, "panda_hand_tcp"),
    ("solo12", "solo12.urdf", False, "FL_FOOT"),
    ("solo12_floating", "solo12.urdf", True, "FL_FOOT"),
]

CONTINUOUS_NOTE = (
    "continuous joints: q holds the angle theta, Pinocchio's (cos, sin) converted"
)
FLOATING_NOTE = (
    "floating root joint (Pinocchio JointModelFreeFlyer, first joint): "
    "q = [x, y, z, qx, qy, qz, qw] = position of the base frame origin in the "
    "world and the unit quaternion of the base-to-world rotation (drawn with "
    "qw >= 0); its 6 velocity components are [linear, angular] of the base "
    "expressed in the BASE (local) frame, as Pinocchio has them (v, a, tau, "
    "mass_matrix, rnea, aba and point_jacobian columns all use this convention; "
    "'a' is the derivative of that local spatial velocity, not the classical "
    "acceleration of the base origin)"
)


def sha256(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def urdf_joints(path):
    """name -> (type, parent link, child link, (lower, upper) or None)."""
    root = ET.parse(path).getroot()
    out = {}
    for j in root.findall("joint"):
        lim = j.find("limit")
        bounds = None
        if lim is not None and "lower" in lim.attrib and "upper" in lim.attrib:
            bounds = (float(lim.attrib["lower"]), float(lim.attrib["upper"]))
        out[j.attrib["name"]] = (
            j.attrib["type"],
            j.find("parent").attrib["link"],
            j.find("child").attrib["link"],
            bounds,
        )
    return out


def joint_kind(jm):
    """Kind of a Pinocchio joint, from its short name."""
    s = jm.shortname()
    if s == "JointModelFreeFlyer":
        return "floating"
    if s.startswith("JointModelRUB") or s == "JointModelRevoluteUnboundedUnaligned":
        return "continuous"
    if s in ("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned"):
        return "revolute"
    if s in ("JointModelPX", "JointModelPY", "JointModelPZ", "JointModelPrismaticUnaligned"):
        return "prismatic"
    raise ValueError("joint type not handled by this generator: " + s)


def joint_axis(jm):
    """Unit axis of a 1-dof joint, in the joint (child) frame."""
    s = jm.shortname()
    for letter, axis in (("X", [1.0, 0.0, 0.0]), ("Y", [0.0, 1.0, 0.0]), ("Z", [0.0, 0.0, 1.0])):
        if s in ("JointModelR" + letter, "JointModelP" + letter, "JointModelRUB" + letter):
            return axis
    if s.endswith("Unaligned"):
        return [float(x) for x in jm.extract().axis]
    return None


class Layout:
    """Maps between the JSON q (continuous joints as one angle) and Pinocchio's q."""

    def __init__(self, model):
        self.model = model
        self.kinds = [joint_kind(model.joints[j]) for j in range(1, model.njoints)]
        self.has_continuous = "continuous" in self.kinds
        self.has_floating = "floating" in self.kinds

    def json_nq(self):
        return sum(
            1 if k == "continuous" else self.model.joints[j + 1].nq
            for j, k in enumerate(self.kinds)
        )

    def to_pin(self, qj):
        out, i = [], 0
        for j, k in enumerate(self.kinds):
            jm = self.model.joints[j + 1]
            if k == "continuous":
                out += [math.cos(qj[i]), math.sin(qj[i])]
                i += 1
            else:
                out += list(qj[i:i + jm.nq])
                i += jm.nq
        assert i == len(qj)
        return np.array(out)

    def from_pin(self, q):
        out = []
        for j, k in enumerate(self.kinds):
            jm = self.model.joints[j + 1]
            seg = q[jm.idx_q:jm.idx_q + jm.nq]
            if k == "continuous":
                out.append(math.atan2(seg[1], seg[0]))
            else:
                out += list(seg)
        return out


def draw_q(rng, model, layout):
    """One configuration, JSON convention (angles for continuous joints)."""
    qj = []
    for j, k in enumerate(layout.kinds):
        jm = model.joints[j + 1]
        if k in ("revolute", "continuous"):
            qj.append(rng.uniform(-math.pi, math.pi))
        elif k == "prismatic":
            lo = model.lowerPositionLimit[jm.idx_q]
            hi = model.upperPositionLimit[jm.idx_q]
            if np.isfinite(lo) and np.isfinite(hi) and abs(lo) < 1e10 and abs(hi) < 1e10 and lo < hi:
                qj.append(rng.uniform(lo, hi))
            else:
                qj.append(rng.uniform(-math.pi, math.pi))
        elif k == "floating":
            pos = rng.uniform(-1.0, 1.0, 3)
            quat = rng.standard_normal(4)  # x, y, z, w
            quat /= np.linalg.norm(quat)
            if quat[3] < 0:
                quat = -quat
            qj += list(pos) + list(quat)
        else:
            raise ValueError(k)
    return [float(x) for x in qj]


def point_jacobian(model, data, q, fid, point):
    """World position of the point and its 3 x nv Jacobian (world components)."""
    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    pin.computeJointJacobians(model, data, q)
    oMf = data.oMf[fid]
    r = oMf.rotation @ point  # link origin -> point, world components
    pos = oMf.translation + r
    J6 = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    Jlin, Jang = J6[:3, :], J6[3:, :]
    # v_point = v_origin + w x r = v_origin - r x w
    J = Jlin - pin.skew(r) @ Jang
    return pos.copy(), J


def point_position(model, data, q, fid, point):
    pin.framesForwardKinematics(model, data, q)
    oMf = data.oMf[fid]
    return oMf.translation + oMf.rotation @ point


def check_jacobian(model, data, q, fid, point, J):
    for i in range(model.nv):
        dv = np.zeros(model.nv)
        dv[i] = FD_EPS
        pp = point_position(model, data, pin.integrate(model, q, dv), fid, point)
        pm = point_position(model, data, pin.integrate(model, q, -dv), fid, point)
        fd = (pp - pm) / (2 * FD_EPS)
        err = np.max(np.abs(fd - J[:, i]))
        if err > FD_TOL:
            raise AssertionError(
                "point Jacobian column %d differs from finite differences by %g" % (i, err)
            )


def mass_matrix(model, data, q):
    M = pin.crba(model, data, q).copy()
    iu = np.triu_indices(model.nv, 1)
    M[(iu[1], iu[0])] = M[iu]  # fill lower from upper
    return M


def rk4_motion(model, data, layout, qj0):
    """1 s of free motion under gravity (tau = 0) from (q0, v = 0), classical RK4."""
    h = MOTION_H
    steps = int(round(MOTION_T / h))
    tau = np.zeros(model.nv)

    def acc(qj, v):
        return pin.aba(model, data, layout.to_pin(qj), v, tau).copy()

    if layout.has_floating:
        # q on the configuration manifold; every stage position and the final
        # update go through pinocchio.integrate(q, dt * velocity).
        q = layout.to_pin(qj0)
        v = np.zeros(model.nv)
        for _ in range(steps):
            k1v = v
            k1a = pin.aba(model, data, q, v, tau).copy()
            q2 = pin.integrate(model, q, 0.5 * h * k1v)
            k2v = v + 0.5 * h * k1a
            k2a = pin.aba(model, data, q2, k2v, tau).copy()
            q3 = pin.integrate(model, q, 0.5 * h * k2v)
            k3v = v + 0.5 * h * k2a
            k3a = pin.aba(model, data, q3, k3v, tau).copy()
            q4 = pin.integrate(model, q, h * k3v)
            k4v = v + h * k3a
            k4a = pin.aba(model, data, q4, k4v, tau).copy()
            q = pin.integrate(model, q, (h / 6.0) * (k1v + 2 * k2v + 2 * k3v + k4v))
            v = v + (h / 6.0) * (k1a + 2 * k2a + 2 * k3a + k4a)
        return layout.from_pin(q), v

    # No floating joint: the JSON q (angles for continuous joints) has one
    # coordinate per velocity, and q' = v holds coordinate-wise.
    q = np.array(qj0)
    assert q.shape[0] == model.nv
    v = np.zeros(model.nv)
    for _ in range(steps):
        k1q, k1v = v, acc(q, v)
        k2q, k2v = v + 0.5 * h * k1v, acc(q + 0.5 * h * k1q, v + 0.5 * h * k1v)
        k3q, k3v = v + 0.5 * h * k2v, acc(q + 0.5 * h * k2q, v + 0.5 * h * k2v)
        k4q, k4v = v + h * k3v, acc(q + h * k3q, v + h * k3v)
        q = q + (h / 6.0) * (k1q + 2 * k2q + 2 * k3q + k4q)
        v = v + (h / 6.0) * (k1v + 2 * k2v + 2 * k3v + k4v)
    return list(q), v


def floats(a):
    return [float(x) for x in np.asarray(a).ravel()]


def rows(a):
    return [floats(r) for r in np.asarray(a)]


def build(name, urdf, floating, link):
    path = os.path.join(HERE, urdf)
    if floating:
        model = pin.buildModelFromUrdf(path, pin.JointModelFreeFlyer())
    else:
        model = pin.buildModelFromUrdf(path)
    data = model.createData()
    assert np.allclose(model.gravity.linear, [0.0, 0.0, -9.81])
    fid = model.getFrameId(link, pin.FrameType.BODY)
    assert fid < len(model.frames), link
    point = np.array(POINT)
    layout = Layout(model)
    ujoints = urdf_joints(path)

    joints = []
    for j in range(1, model.njoints):
        jm = model.joints[j]
        jname = model.names[j]
        kind = layout.kinds[j - 1]
        if jname in ujoints:
            utype, parent, child, _ = ujoints[jname]
            assert utype == kind, (jname, utype, kind)
        else:
            assert kind == "floating" and j == 1
            parent = "universe"
            # The first BODY frame on joint 1 is the URDF root link.
            child = next(f.name for f in model.frames
                         if f.parentJoint == 1 and f.type == pin.FrameType.BODY)
        joints.append({
            "name": jname,
            "type": kind,
            "nq": 1 if kind == "continuous" else int(jm.nq),
            "nv": int(jm.nv),
            "parent_link": parent,
            "child_link": child,
            "pinocchio_type": jm.shortname(),
            "axis": joint_axis(jm),
        })

    rng = np.random.default_rng(SEED)
    samples = []
    for _ in range(N_SAMPLES):
        qj = draw_q(rng, model, layout)
        v = rng.uniform(-1.0, 1.0, model.nv)
        a = rng.uniform(-1.0, 1.0, model.nv)
        tau = rng.uniform(-1.0, 1.0, model.nv)
        q = layout.to_pin(qj)

        M = mass_matrix(model, data, q)
        tau_id = pin.rnea(model, data, q, v, a).copy()
        ddq = pin.aba(model, data, q, v, tau).copy()
        pos, J = point_jacobian(model, data, q, fid, point)

        # Self-checks.
        Mfull = pin.crba(model, data, q)
        assert np.allclose(np.triu(Mfull), np.triu(M), rtol=0, atol=0)
        nle = pin.rnea(model, data, q, v, np.zeros(model.nv))
        assert np.allclose(M @ a + nle, tau_id, rtol=1e-9, atol=1e-9)
        assert np.allclose(pin.rnea(model, data, q, v, ddq), tau, rtol=1e-8, atol=1e-8)
        assert np.allclose(layout.to_pin(layout.from_pin(q)), q)
        check_jacobian(model, data, q, fid, point, J)

        samples.append({
            "q": floats(qj),
            "v": floats(v),
            "a": floats(a),
            "tau": floats(tau),
            "mass_matrix": rows(M),
            "rnea": floats(tau_id),
            "aba": floats(ddq),
            "point_jacobian": rows(J),
            "point_position": floats(pos),
        })

    notes = [CONTINUOUS_NOTE]
    if floating:
        notes.append(FLOATING_NOTE)
    notes.append(
        "draws (numpy default_rng(%d), fresh for this file): per sample q joint by "
        "joint in Pinocchio order (revolute and continuous: uniform [-pi, pi]; "
        "prismatic: uniform within its URDF limits; floating: position uniform "
        "[-1, 1]^3 then a quaternion from 4 standard normals, normalised, sign "
        "so that qw >= 0), then v, a, tau uniform [-1, 1]^nv" % SEED
    )
    notes.append(
        "point_jacobian: 3 x nv, d(point_position)/dt = point_jacobian @ v; the "
        "point is frame.point in the axes of the link frame (URDF link frame = "
        "Pinocchio BODY frame of frame.link); checked against central finite "
        "differences (pinocchio.integrate, eps %g) to %g" % (FD_EPS, FD_TOL)
    )
    notes.append("mass_matrix: pinocchio.crba, lower triangle filled from the upper")
    notes.append(
        "URDF <dynamics> damping/friction is stored by Pinocchio (model.damping) but "
        "not used by crba/rnea/aba, so it is absent from every value here; "
        "<transmission> is ignored; <mimic> is ignored (buildModelFromUrdf's default "
        "mimic=False): a mimic joint is an independent joint here"
    )

    out = {
        "robot": name,
        "pinocchio": pin.__version__,
        "source": urdf,
        "source_sha256": sha256(path),
        "root_joint": "JointModelFreeFlyer" if floating else "fixed",
        "gravity": floats(model.gravity.linear),
        "seed": SEED,
        "note": "; ".join(notes),
        "nq": layout.json_nq(),
        "nv": int(model.nv),
        "joints": joints,
        "frame": {"link": link, "point": list(POINT)},
        "samples": samples,
    }

    q0 = samples[0]["q"]
    q1, v1 = rk4_motion(model, data, layout, q0)
    motion = {"h": MOTION_H, "t": MOTION_T, "q0": floats(q0), "q1": floats(q1), "v1": floats(v1)}
    if floating:
        motion["scheme"] = (
            "classical RK4 on (q, v), v(0) = 0, tau = 0; stage positions "
            "q_k = integrate(q, c_k h v_k) and the update "
            "q_next = integrate(q, h/6 (v1 + 2 v2 + 2 v3 + v4)), with pinocchio.integrate"
        )
    else:
        motion["scheme"] = (
            "classical RK4 on (q, v) in the JSON q convention (angles), v(0) = 0, tau = 0, "
            "accelerations from pinocchio.aba"
        )
    out["motion"] = motion

    dst = os.path.join(HERE, name + ".json")
    with open(dst, "w") as f:
        json.dump(out, f, separators=(",", ":"))
        f.write("\n")
    return dst


def main():
    t0 = time.time()
    for name, urdf, floating, link in ROBOTS:
        t = time.time()
        dst = build(name, urdf, floating, link)
        print("%-28s %9d bytes  %5.1f s" % (os.path.basename(dst), os.path.getsize(dst), time.time() - t))
    print("pinocchio %s, total %.1f s" % (pin.__version__, time.time() - t0))


if __name__ == "__main__":
    sys.exit(main())
