#!/usr/bin/env python3
"""Independent reference values for the derivatives of the dynamics of robots read from URDF.

Run by hand (like reference.py next to it), with a Python that has Pinocchio:

    python3 -m venv /some/venv
    /some/venv/bin/pip install pin numpy
    /some/venv/bin/python tests/data/robots/derivatives.py

It reads the URDF files next to itself and writes `<robot>_derivatives.json` next to
itself: ur5, panda (fixed base) and solo12_floating (solo12.urdf under a free-flyer root
joint). It imports the model conventions (Layout, draw_q, joint kinds and axes) from
reference.py in the same folder, so q, v and the joint list mean exactly what they mean in
`<robot>.json`.

Every model is `pinocchio.buildModelFromUrdf(path)` (fixed base), or
`pinocchio.buildModelFromUrdf(path, pinocchio.JointModelFreeFlyer())`, with Pinocchio's
default gravity (0, 0, -9.81); <mimic> is ignored (buildModelFromUrdf's default
mimic=False), URDF damping is not used. Per sample it writes rnea and its derivatives
(pinocchio.computeRNEADerivatives), aba and its derivatives with the inverse mass matrix
(pinocchio.computeABADerivatives) and, for fixed bases and the first N_PHI samples, the
exact Jacobians of one classical RK4 step and of one semi-implicit Euler step (h = H, tau
held) by the chain rule.

Each value written is checked before it is written:
  * rnea(q, v, aba(q, v, tau)) == tau to 1e-8;
  * every derivative matrix against central finite differences of pinocchio.rnea /
    pinocchio.aba along pinocchio.integrate(q, +-eps e_i) and v +- eps e_i, to 1e-5 of the
    matrix's largest entry;
  * minv @ M == I to 1e-9 (M from pinocchio.crba, lower triangle filled from the upper);
  * rk4_phi and euler_phi against central finite differences of the step, to 1e-5 of the
    largest entry.
"""

import json
import os
import sys
import time

import numpy as np
import pinocchio as pin

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.dont_write_bytecode = True  # no __pycache__ next to the data
from reference import (  # noqa: E402  (same folder; defines the conventions of <robot>.json)
    CONTINUOUS_NOTE,
    Layout,
    draw_q,
    floats,
    joint_axis,
    mass_matrix,
    rows,
    sha256,
    urdf_joints,
)

SEED = 4099
H = 1e-3
N_PHI = 20
FD_EPS = 1e-6
FD_TOL = 1e-5  # relative to the largest entry of the matrix checked
ID_TOL = 1e-8  # rnea(q, v, aba) == tau
MINV_TOL = 1e-9  # minv @ M == I

# (output name, URDF file, floating root?, number of samples)
ROBOTS = [
    ("ur5", "ur5.urdf", False, 100),
    ("panda", "panda.urdf", False, 100),
    ("solo12_floating", "solo12.urdf", True, 50),
]

FLOATING_NOTE = (
    "floating root joint (Pinocchio JointModelFreeFlyer, first joint): q = [x, y, z, qx, "
    "qy, qz, qw] = position of the base frame origin in the world and the unit quaternion "
    "of the base-to-world rotation (drawn with qw >= 0); its 6 velocity components are "
    "[linear, angular] of the base expressed in the BASE (local) frame, as Pinocchio has "
    "them; v, a, tau, rnea, aba and the rows and columns of every matrix use this "
    "convention ('a' and 'aba' are derivatives of that local spatial velocity, not the "
    "classical acceleration of the base origin)"
)

TANGENT_NOTE = (
    "derivatives with respect to q are in Pinocchio's tangent space (nv columns): column "
    "i of d/dq is d/ds f(q (+) s e_i) at s = 0, with q (+) d = pinocchio.integrate(model, "
    "q, d); for revolute and prismatic joints (and continuous joints, as the angle) this "
    "is the ordinary partial derivative, for the free flyer it moves the base by "
    "exp(d) in its LOCAL frame (d = [linear, angular] in base axes), with v, a, tau held "
    "as they are (local components)"
)


def joint_list(model, layout, path):
    """The "joints" list of <robot>.json (same code as reference.py's build)."""
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
    return joints


class Worst:
    """Largest error seen per check, for the summary line."""

    def __init__(self):
        self.e = {}

    def add(self, key, err, tol):
        if not err <= tol:
            raise AssertionError("%s: error %g above %g" % (key, err, tol))
        self.e[key] = max(self.e.get(key, 0.0), err)


def rel_err(A, B):
    """max |A - B| over the largest entry of B."""
    return float(np.max(np.abs(A - B)) / max(np.max(np.abs(B)), 1e-300))


def fd_dq(model, f, q):
    """Central differences of f along pinocchio.integrate(q, +-eps e_i), one column per i."""
    cols = []
    for i in range(model.nv):
        d = np.zeros(model.nv)
        d[i] = FD_EPS
        cols.append((f(pin.integrate(model, q, d)) - f(pin.integrate(model, q, -d))) / (2 * FD_EPS))
    return np.array(cols).T


def fd_dv(f, v):
    cols = []
    for i in range(v.shape[0]):
        d = np.zeros(v.shape[0])
        d[i] = FD_EPS
        cols.append((f(v + d) - f(v - d)) / (2 * FD_EPS))
    return np.array(cols).T


def fd_dx(f, x):
    return fd_dv(f, x)


def aba_derivs(model, data, q, v, tau):
    dq, dv, minv = pin.computeABADerivatives(model, data, q, v, tau)
    return data.ddq.copy(), dq.copy(), dv.copy(), minv.copy()


def rk4_step(model, data, layout, x, tau, h):
    """One classical RK4 step of x = (q, v), q in the JSON convention (one coordinate per dof)."""
    n = model.nv

    def f(x):
        return np.concatenate([x[n:], pin.aba(model, data, layout.to_pin(list(x[:n])), x[n:], tau)])

    k1 = f(x)
    k2 = f(x + 0.5 * h * k1)
    k3 = f(x + 0.5 * h * k2)
    k4 = f(x + h * k3)
    return x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)


def rk4_phi(model, data, layout, x, tau, h):
    """Exact Jacobian of rk4_step (the formula of the peers' gen_ref.py rk4_phi)."""
    n = model.nv

    def f(x):
        a, dq, dv, _ = aba_derivs(model, data, layout.to_pin(list(x[:n])), x[n:], tau)
        J = np.zeros((2 * n, 2 * n))
        J[:n, n:] = np.eye(n)
        J[n:, :n] = dq
        J[n:, n:] = dv
        return np.concatenate([x[n:], a]), J

    I = np.eye(2 * n)
    k1, J1 = f(x)
    d1 = J1
    k2, J2 = f(x + 0.5 * h * k1)
    d2 = J2 @ (I + 0.5 * h * d1)
    k3, J3 = f(x + 0.5 * h * k2)
    d3 = J3 @ (I + 0.5 * h * d2)
    k4, J4 = f(x + h * k3)
    d4 = J4 @ (I + h * d3)
    return I + h / 6.0 * (d1 + 2 * d2 + 2 * d3 + d4)


def euler_step(model, data, layout, x, tau, h):
    """Semi-implicit Euler: v1 = v + h aba(q, v, tau); q1 = q + h v1."""
    n = model.nv
    q, v = x[:n], x[n:]
    v1 = v + h * pin.aba(model, data, layout.to_pin(list(q)), v, tau)
    return np.concatenate([q + h * v1, v1])


def euler_phi(daba_dq, daba_dv, h):
    n = daba_dq.shape[0]
    I = np.eye(n)
    dv1 = np.hstack([h * daba_dq, I + h * daba_dv])
    dq1 = np.hstack([I, np.zeros((n, n))]) + h * dv1
    return np.vstack([dq1, dv1])


def build(name, urdf, floating, n_samples, worst, minv_filled):
    path = os.path.join(HERE, urdf)
    if floating:
        model = pin.buildModelFromUrdf(path, pin.JointModelFreeFlyer())
    else:
        model = pin.buildModelFromUrdf(path)
    data = model.createData()
    fdata = model.createData()  # for the finite differences
    assert np.allclose(model.gravity.linear, [0.0, 0.0, -9.81])
    layout = Layout(model)
    joints = joint_list(model, layout, path)
    nv = model.nv
    fixed = not layout.has_floating
    if fixed:
        assert layout.json_nq() == nv  # one coordinate per velocity: x = (q, v) is Euclidean

    rng = np.random.default_rng(SEED)
    samples = []
    for k in range(n_samples):
        qj = draw_q(rng, model, layout)
        v = rng.uniform(-2.0, 2.0, nv)
        a = rng.uniform(-1.0, 1.0, nv)
        tau = rng.uniform(-1.0, 1.0, nv)
        q = layout.to_pin(qj)
        assert np.allclose(layout.to_pin(layout.from_pin(q)), q)

        tau_id = pin.rnea(model, data, q, v, a).copy()
        drnea_dq, drnea_dv, drnea_da = [x.copy() for x in pin.computeRNEADerivatives(model, data, q, v, a)]
        ddq = pin.aba(model, data, q, v, tau).copy()
        ddq_d, daba_dq, daba_dv, minv = aba_derivs(model, data, q, v, tau)

        # Minv: fill the strictly lower triangle from the upper if Pinocchio left it empty
        # (pin 4.1.0's Python binding returns it full and exactly symmetric).
        il = np.tril_indices(nv, -1)
        if not np.any(minv[il]):
            minv[il] = minv.T[il]
            minv_filled[0] += 1
        minv_filled[1] += 1
        assert np.array_equal(minv, minv.T), "minv not symmetric"

        # Self-checks.
        worst.add("aba from computeABADerivatives vs aba (rel)", rel_err(ddq_d, ddq), 1e-9)
        worst.add("rnea(q,v,aba)-tau (abs)",
                  float(np.max(np.abs(pin.rnea(model, fdata, q, v, ddq) - tau))), ID_TOL)
        M = mass_matrix(model, fdata, q)
        worst.add("minv@M-I (abs)", float(np.max(np.abs(minv @ M - np.eye(nv)))), MINV_TOL)
        worst.add("drnea_da vs crba M (rel)", rel_err(drnea_da, M), 1e-12)

        def rnea_q(qq):
            return pin.rnea(model, fdata, qq, v, a).copy()

        def rnea_v(vv):
            return pin.rnea(model, fdata, q, vv, a).copy()

        def aba_q(qq):
            return pin.aba(model, fdata, qq, v, tau).copy()

        def aba_v(vv):
            return pin.aba(model, fdata, q, vv, tau).copy()

        worst.add("drnea_dq vs FD (rel)", rel_err(drnea_dq, fd_dq(model, rnea_q, q)), FD_TOL)
        worst.add("drnea_dv vs FD (rel)", rel_err(drnea_dv, fd_dv(rnea_v, v)), FD_TOL)
        worst.add("daba_dq vs FD (rel)", rel_err(daba_dq, fd_dq(model, aba_q, q)), FD_TOL)
        worst.add("daba_dv vs FD (rel)", rel_err(daba_dv, fd_dv(aba_v, v)), FD_TOL)

        s = {
            "q": floats(qj),
            "v": floats(v),
            "a": floats(a),
            "tau": floats(tau),
            "rnea": floats(tau_id),
            "drnea_dq": rows(drnea_dq),
            "drnea_dv": rows(drnea_dv),
            "aba": floats(ddq),
            "daba_dq": rows(daba_dq),
            "daba_dv": rows(daba_dv),
            "minv": rows(minv),
        }
        if fixed and k < N_PHI:
            x = np.concatenate([np.array(qj), v])
            P = rk4_phi(model, data, layout, x, tau, H)
            E = euler_phi(daba_dq, daba_dv, H)
            worst.add("rk4_phi vs FD (rel)",
                      rel_err(P, fd_dx(lambda y: rk4_step(model, fdata, layout, y, tau, H), x)), FD_TOL)
            worst.add("euler_phi vs FD (rel)",
                      rel_err(E, fd_dx(lambda y: euler_step(model, fdata, layout, y, tau, H), x)), FD_TOL)
            s["rk4_phi"] = rows(P)
            s["euler_phi"] = rows(E)
        samples.append(s)

    notes = [
        "fields: robot; pinocchio (the version that computed every value); source and "
        "source_sha256 (the URDF next to this file); root_joint ('fixed' or "
        "'JointModelFreeFlyer'); gravity (world, m/s^2); seed; nq (length of the JSON q) and "
        "nv; joints (as in <robot>.json: Pinocchio's joint order, which is the order of q, "
        "v and of every matrix row and column); h (the step of rk4_phi and euler_phi); "
        "samples, each with q (JSON convention, nq), v, a, tau (nv), and the values below",
        CONTINUOUS_NOTE,
    ]
    if floating:
        notes.append(FLOATING_NOTE)
    notes.append(TANGENT_NOTE)
    notes.append(
        "draws (numpy default_rng(%d), fresh for this file): per sample q joint by joint "
        "in Pinocchio order (revolute and continuous: uniform [-pi, pi]; prismatic: uniform "
        "within its URDF limits; floating: position uniform [-1, 1]^3 then a quaternion "
        "from 4 standard normals, normalised, sign so that qw >= 0), then v uniform "
        "[-2, 2]^nv, a and tau uniform [-1, 1]^nv" % SEED
    )
    notes.append(
        "rnea = pinocchio.rnea(q, v, a); drnea_dq, drnea_dv = d rnea/dq, d rnea/dv from "
        "pinocchio.computeRNEADerivatives(q, v, a) (nv x nv, list of rows: entry [i][j] "
        "= d rnea_i / d x_j)"
    )
    notes.append(
        "aba = pinocchio.aba(q, v, tau); daba_dq, daba_dv = d aba/dq, d aba/dv and minv = "
        "d aba/d tau = M(q)^-1, all from pinocchio.computeABADerivatives(q, v, tau) "
        "(nv x nv, rows; minv is symmetric: %s)" % (
            "Pinocchio %s returned it full and exactly symmetric in every sample" % pin.__version__
            if minv_filled[0] == 0 else
            "its strictly lower triangle, left empty by Pinocchio %s in %d of %d samples, was "
            "filled from the upper" % (pin.__version__, minv_filled[0], minv_filled[1]))
    )
    if not floating:
        notes.append(
            "first %d samples only: rk4_phi and euler_phi, 2nv x 2nv (rows), the exact "
            "Jacobian d x1 / d x of one step of the state x = (q, v) (q as in the JSON, "
            "Euclidean, first nv entries; then v; rows x1 = (q1, v1), columns x = (q, v)), "
            "h = %g, tau held: rk4_phi of classical "
            "RK4 on x' = (v, aba(q, v, tau)), x1 = x + h/6 (k1 + 2 k2 + 2 k3 + k4), by the "
            "chain rule through the four stages with computeABADerivatives at each stage; "
            "euler_phi of semi-implicit Euler v1 = v + h aba(q, v, tau), q1 = q + h v1 "
            "(d v1/dx = [h daba_dq, I + h daba_dv], d q1/dx = [I, 0] + h d v1/dx)" % (N_PHI, H)
        )
    notes.append(
        "checked before writing: rnea(q, v, aba) == tau to %g; drnea_dq, drnea_dv, "
        "daba_dq, daba_dv against central finite differences of pinocchio.rnea / "
        "pinocchio.aba along pinocchio.integrate(q, +-eps e_i) and v +- eps e_i (eps %g) "
        "to %g of the matrix's largest entry; minv @ M == I to %g (M = pinocchio.crba, "
        "symmetric)%s" % (
            ID_TOL, FD_EPS, FD_TOL, MINV_TOL,
            "" if floating else
            "; rk4_phi and euler_phi against central finite differences of the step (eps "
            "%g) to %g of the largest entry" % (FD_EPS, FD_TOL))
    )
    notes.append(
        "URDF <dynamics> damping/friction is not used by rnea/aba or their derivatives; "
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
        "nv": int(nv),
        "joints": joints,
        "h": H,
        "samples": samples,
    }
    dst = os.path.join(HERE, name + "_derivatives.json")
    with open(dst, "w") as f:
        json.dump(out, f, separators=(",", ":"), allow_nan=False)
        f.write("\n")
    return dst


def main():
    t0 = time.time()
    for name, urdf, floating, n in ROBOTS:
        t = time.time()
        worst = Worst()
        minv_filled = [0, 0]
        dst = build(name, urdf, floating, n, worst, minv_filled)
        print("%-36s %9d bytes  %5.1f s" % (os.path.basename(dst), os.path.getsize(dst), time.time() - t))
        for key, e in worst.e.items():
            print("    worst %-44s %.3g" % (key, e))
        print("    minv lower triangle filled by this script in %d of %d samples" % tuple(minv_filled))
    print("pinocchio %s, total %.1f s" % (pin.__version__, time.time() - t0))


if __name__ == "__main__":
    sys.exit(main())
