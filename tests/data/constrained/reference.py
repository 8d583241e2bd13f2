#!/usr/bin/env python3
"""Pinocchio 4.1 reference values for dynamics under rigid bilateral constraints.

Run by hand from the repository root, with a Python that has Pinocchio 4.1.0:

    python3 -m venv /tmp/pinenv && /tmp/pinenv/bin/pip install pin==4.1.0
    /tmp/pinenv/bin/python tests/data/constrained/reference.py

It writes `tests/data/constrained/reference.json` (see README.md next to this file).

Five cases: Solo12 (tests/data/robots/solo12.urdf under a free-flyer root) with 3D point
contacts at its four feet (LOCAL_WORLD_ALIGNED) or at two diagonal feet (LOCAL); the UR5
(tests/data/robots/ur5.urdf, fixed base) with tool0 welded to the world (6D, LOCAL); and a
planar four-bar linkage built in code, closed by a 3D point constraint either from the end
of a serial chain to the world (`fourbar_serial`) or between two branches
(`fourbar_branch`). For every sample it stores Pinocchio's constraintDynamics
(ddq, lambda), the constraint Jacobian, the drift gamma (J ddq + gamma = 0), the output
of computeConstraintDynamicsDerivatives and, for the four-foot case, impulseDynamics
(restitution 0) with computeImpulseDynamicsDerivatives. Every value is checked against
forward kinematics, the equations of motion (rnea) and central differences.
"""

import json
import os
import sys

import numpy as np
import pinocchio as pin

HERE = os.path.dirname(os.path.abspath(__file__))
ROBOTS = os.path.join(HERE, "..", "robots")
OUT = os.path.join(HERE, "reference.json")

SEED = 4141          # case i (in CASES order) draws from np.random.default_rng(SEED + i)
N_SAMPLES = 4
EPS = 1e-6           # central-difference step (q moved with pin.integrate)
FLAG = 1e-5          # a derivative further than this from central differences is flagged
SIGMA_MIN = 0.02     # redraw while the smallest nonzero singular value of J is below this

LOCAL, LWA = pin.ReferenceFrame.LOCAL, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
C3D, C6D = pin.ContactType.CONTACT_3D, pin.ContactType.CONTACT_6D
# Exact rigid contact: one Cholesky solve, no regularisation (Pinocchio's default settings).
EXACT = (1e-12, 1e-12, 0.0, 1)
# Planar loops closed by a 3D point leave one row of J identically zero: mu = 0 gives NaN,
# so the four-bars use a small proximal mu (as Pinocchio's own closed-chain example).
PROXIMAL = (1e-12, 1e-12, 1e-10, 10)
FEET = ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"]

# Four-bar: pivots A = (0,0,0), B = (1,0,0); crank a, coupler b, rocker c; bars 1 kg/m, radius r.
A_LEN, B_LEN, C_LEN, GROUND, RADIUS = 0.3, 1.0, 0.8, 1.0, 0.02


# ------------------------------------------------------------------ models and constraints

def translation(x):
    return pin.SE3(np.eye(3), np.array([x, 0.0, 0.0]))


def rod(length):
    """Solid cylinder along x from the joint origin: 1 kg/m, radius RADIUS."""
    m = length
    transverse = m * (3 * RADIUS**2 + length**2) / 12
    return pin.Inertia(m, np.array([length / 2, 0.0, 0.0]),
                       np.diag([m * RADIUS**2 / 2, transverse, transverse]))


def fourbar(branch):
    """Joints about y (motion in the x-z plane). Returns the model and its one constraint
    (frame, type, reference, joint1, placement1, joint2, placement2)."""
    model = pin.Model()  # gravity (0, 0, -9.81)
    crank = model.addJoint(0, pin.JointModelRY(), pin.SE3.Identity(), "crank")
    model.appendBodyToJoint(crank, rod(A_LEN), pin.SE3.Identity())
    coupler = model.addJoint(crank, pin.JointModelRY(), translation(A_LEN), "coupler")
    model.appendBodyToJoint(coupler, rod(B_LEN), pin.SE3.Identity())
    if branch:   # rocker hangs on the world at B; coupler tip held to rocker tip
        rocker = model.addJoint(0, pin.JointModelRY(), translation(GROUND), "rocker")
        con = (None, C3D, LOCAL, coupler, translation(B_LEN), rocker, translation(C_LEN))
    else:        # rocker continues the chain; rocker tip held to the world point B
        rocker = model.addJoint(coupler, pin.JointModelRY(), translation(B_LEN), "rocker")
        con = (None, C3D, LOCAL, rocker, translation(C_LEN), 0, translation(GROUND))
    model.appendBodyToJoint(rocker, rod(C_LEN), pin.SE3.Identity())
    return model, [con]


def frame_constraints(model, frames, ctype, ref):
    """Each frame held to the world where it is (placement2 None: set from q per sample)."""
    out = []
    for name in frames:
        frame = model.frames[model.getFrameId(name)]
        out.append((name, ctype, ref, frame.parentJoint, frame.placement, 0, None))
    return out


def build(case):
    """(model, constraints, proximal settings, description, model source)."""
    if case.startswith("solo12"):
        model = pin.buildModelFromUrdf(os.path.join(ROBOTS, "solo12.urdf"), pin.JointModelFreeFlyer())
        src = "tests/data/robots/solo12.urdf, pin.JointModelFreeFlyer() root"
        if case == "solo12_4feet_lwa":
            return model, frame_constraints(model, FEET, C3D, LWA), EXACT, \
                "3D point contacts of the four feet with the world, LOCAL_WORLD_ALIGNED", src
        return model, frame_constraints(model, ["FL_FOOT", "HR_FOOT"], C3D, LOCAL), EXACT, \
            "3D point contacts of FL_FOOT and HR_FOOT with the world (trot), LOCAL", src
    if case == "ur5_weld_local":
        model = pin.buildModelFromUrdf(os.path.join(ROBOTS, "ur5.urdf"))
        return model, frame_constraints(model, ["tool0"], C6D, LOCAL), EXACT, \
            "6D weld of tool0 to the world, LOCAL", "tests/data/robots/ur5.urdf, fixed base"
    branch = case == "fourbar_branch"
    model, cons = fourbar(branch)
    desc = ("coupler tip held to rocker tip (two moving bodies)" if branch
            else "rocker tip (end of a serial chain) held to the world point B")
    return model, cons, PROXIMAL, "planar four-bar, 3D point constraint, LOCAL: " + desc, \
        "built in code (README.md)"


CASES = ["solo12_4feet_lwa", "solo12_trot_local", "ur5_weld_local", "fourbar_serial", "fourbar_branch"]


def constraint_models(model, cons, q):
    """Pinocchio constraint models; world anchors at the frames' placements at q; gains 0."""
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    cms = pin.StdVec_RigidConstraintModel()
    for name, ctype, ref, j1, m1, j2, m2 in cons:
        cm = pin.RigidConstraintModel(ctype, model, j1, m1, j2, data.oMi[j1] * m1 if m2 is None else m2, ref)
        cm.m_baumgarte_parameters.Kp = 0.0
        cm.m_baumgarte_parameters.Kd = 0.0
        cms.append(cm)
    return cms


# ------------------------------------------------------------------ Pinocchio calls

def forward(model, cms, settings, q, v, tau):
    """constraintDynamics: (ddq, lambda, J, data, settings) at (q, v, tau)."""
    data = model.createData()
    cds = pin.StdVec_RigidConstraintData()
    for cm in cms:
        cds.append(cm.createData())
    ps = pin.ProximalSettings(*settings)
    pin.initConstraintDynamics(model, data, cms, cds)
    ddq = pin.constraintDynamics(model, data, q, v, tau, cms, cds, ps).copy()
    J = pin.getConstraintsJacobian(model, data, cms, cds).copy()
    return ddq, data.lambda_c.copy(), J, (data, cds, ps)


def impact(model, cms, settings, q, v):
    """impulseDynamics with restitution 0: (v_after, impulse, data, settings)."""
    data = model.createData()
    cds = pin.StdVec_RigidConstraintData()
    for cm in cms:
        cds.append(cm.createData())
    ps = pin.ProximalSettings(*settings)
    pin.initConstraintDynamics(model, data, cms, cds)
    vplus = pin.impulseDynamics(model, data, q, v, cms, cds, 0.0, ps).copy()
    return vplus, data.impulse_c.copy(), (data, cds, ps)


def constraint_acceleration(model, cms, q, v, a):
    """Acceleration of the constraints from forward kinematics alone: for 3D, the classical
    acceleration of point 1 minus point 2 (world axes for LOCAL_WORLD_ALIGNED, frame-1 axes
    for LOCAL); for a 6D LOCAL weld to the world, the frame's spatial acceleration in its own
    axes. At a = 0 this is the drift gamma, so that J a + gamma = 0 on the constraint."""
    data = model.createData()
    pin.forwardKinematics(model, data, q, v, a)

    def point(j, placement):  # (world rotation of the frame, classical acceleration in world axes)
        oMf = data.oMi[j] * placement
        vel, acc = placement.actInv(data.v[j]), placement.actInv(data.a[j])
        return oMf.rotation, oMf.rotation @ (acc.linear + np.cross(vel.angular, vel.linear))

    out = []
    for cm in cms:
        R1, a1 = point(cm.joint1_id, cm.joint1_placement)
        if cm.type == C6D:
            assert cm.joint2_id == 0 and cm.reference_frame == LOCAL
            out.append(cm.joint1_placement.actInv(data.a[cm.joint1_id]).vector)
            continue
        a2 = point(cm.joint2_id, cm.joint2_placement)[1] if cm.joint2_id else np.zeros(3)
        out.append(R1.T @ (a1 - a2) if cm.reference_frame == LOCAL else a1 - a2)
    return np.concatenate(out)


def central_differences(f, x, n, step):
    """Columns d/ds f(step(x, s e_i)) at s = 0 for every output of f (a tuple of arrays)."""
    cols = []
    for i in range(n):
        e = np.zeros(n)
        e[i] = EPS
        plus, minus = f(step(x, e)), f(step(x, -e))
        cols.append([(p - m) / (2 * EPS) for p, m in zip(plus, minus)])
    return [np.column_stack([c[k] for c in cols]) for k in range(len(cols[0]))]


def rel_err(analytical, fd):
    return float(np.abs(analytical - fd).max() / max(1.0, np.abs(fd).max()))


# ------------------------------------------------------------------ states

def wrap(x):
    return (x + np.pi) % (2 * np.pi) - np.pi


def random_state(model, rng):
    """Free flyer: position U[-0.5,0.5]^3, quaternion from 4 normals (w >= 0); revolute angles
    U[-pi,pi]; v U[-2,2]^nv; tau U[-2,2] on actuated joints, 0 on the free flyer."""
    q = np.zeros(model.nq)
    tau = np.zeros(model.nv)
    for jm in model.joints[1:]:
        if jm.shortname() == "JointModelFreeFlyer":
            quat = rng.normal(size=4)
            quat *= np.sign(quat[3]) / np.linalg.norm(quat)   # [qx, qy, qz, qw], qw >= 0
            q[jm.idx_q:jm.idx_q + 7] = np.concatenate([rng.uniform(-0.5, 0.5, 3), quat])
        else:
            q[jm.idx_q] = rng.uniform(-np.pi, np.pi)
    v = rng.uniform(-2, 2, model.nv)
    for jm in model.joints[1:]:
        if jm.shortname() != "JointModelFreeFlyer":
            tau[jm.idx_v:jm.idx_v + jm.nv] = rng.uniform(-2, 2, jm.nv)
    return q, v, tau


def closed_state(model, cons, settings, branch, rng):
    """A closed four-bar: crank angle uniform, coupler tip P2 at distance b from the crank tip
    P1 and c from B, on the side of P1 -> B reached by turning +x towards +z. Planar points are
    (x, z); an RY angle h turns x into (cos h, -sin h), so a direction w has heading
    atan2(-w_z, w_x). v = s n (n the unit null vector of J, n[0] >= 0, s U[-2,2]), tau U[-2,2]^3."""
    th1 = rng.uniform(-np.pi, np.pi)
    heading = lambda w: np.arctan2(-w[1], w[0])
    p1 = A_LEN * np.array([np.cos(th1), -np.sin(th1)])
    pb = np.array([GROUND, 0.0])
    d = np.linalg.norm(pb - p1)
    u = (pb - p1) / d
    along = (B_LEN**2 - C_LEN**2 + d**2) / (2 * d)           # circle-circle intersection
    p2 = p1 + along * u + np.sqrt(B_LEN**2 - along**2) * np.array([-u[1], u[0]])
    h2 = heading(p2 - p1)
    third = heading(p2 - pb) if branch else wrap(heading(pb - p2) - h2)
    q = np.array([th1, wrap(h2 - th1), third])
    J = forward(model, constraint_models(model, cons, q), settings, q, np.zeros(3), np.zeros(3))[2]
    n = np.linalg.svd(J)[2][-1]
    v = rng.uniform(-2, 2) * (n if n[0] >= 0 else -n)
    return q, v, rng.uniform(-2, 2, model.nv)


def smallest_singular_value(J):
    s = np.linalg.svd(J, compute_uv=False)
    return s[s > 1e-12].min()


# ------------------------------------------------------------------ one sample

DERIVS = ["ddq_dq", "ddq_dv", "ddq_dtau", "dlambda_dq", "dlambda_dv", "dlambda_dtau"]
IMPULSE_DERIVS = ["dv_after_dq", "dv_after_dv", "dimpulse_dq", "dimpulse_dv"]


def evaluate(case, model, cons, settings, q, v, tau, with_impulse):
    """All stored values at one state, plus its check figures (returned separately)."""
    cms = constraint_models(model, cons, q)   # held fixed for the differences
    ddq, lam, J, (data, cds, ps) = forward(model, cms, settings, q, v, tau)
    der = dict(zip(DERIVS, (x.copy() for x in
                            pin.computeConstraintDynamicsDerivatives(model, data, cms, cds, ps))))
    gamma = constraint_acceleration(model, cms, q, v, np.zeros(model.nv))
    eom = pin.rnea(model, model.createData(), q, v, ddq) - tau - J.T @ lam
    checks = {"J_ddq_plus_gamma": float(np.abs(J @ ddq + gamma).max()),
              "fk_constraint_acceleration": float(np.abs(constraint_acceleration(model, cms, q, v, ddq)).max()),
              "eom_residual": float(np.abs(eom).max()),
              "sigma_min_J": float(smallest_singular_value(J)), "iterations": int(ps.iter)}

    integ = lambda x, e: pin.integrate(model, x, e)
    add = lambda x, e: x + e
    f = lambda qq, vv, tt: forward(model, cms, settings, qq, vv, tt)[:2]
    fd = {}
    fd["ddq_dq"], fd["dlambda_dq"] = central_differences(lambda x: f(x, v, tau), q, model.nv, integ)
    fd["ddq_dv"], fd["dlambda_dv"] = central_differences(lambda x: f(q, x, tau), v, model.nv, add)
    fd["ddq_dtau"], fd["dlambda_dtau"] = central_differences(lambda x: f(q, v, x), tau, model.nv, add)
    checks["fd"] = {k: rel_err(der[k], fd[k]) for k in DERIVS}

    s = {"q": q, "v": v, "tau": tau, "ddq": ddq, "lambda": lam, "constraint_jacobian": J, "gamma": gamma}
    s.update(der)
    if case == "fourbar_branch":  # Pinocchio's d/dq are wrong here: store the differences too
        s["ddq_dq_fd"], s["dlambda_dq_fd"] = fd["ddq_dq"], fd["dlambda_dq"]

    if with_impulse:
        vplus, imp, (idata, icds, ips) = impact(model, cms, settings, q, v)
        pin.computeImpulseDynamicsDerivatives(model, idata, cms, icds, 0.0, ips)
        # Pinocchio leaves d(v_after - v)/dv in data.ddq_dv: add the identity.
        ider = dict(zip(IMPULSE_DERIVS, [idata.ddq_dq.copy(), idata.ddq_dv + np.eye(model.nv),
                                         idata.dlambda_dq.copy(), idata.dlambda_dv.copy()]))
        g = lambda qq, vv: impact(model, cms, settings, qq, vv)[:2]
        ifd = {}
        ifd["dv_after_dq"], ifd["dimpulse_dq"] = central_differences(lambda x: g(x, v), q, model.nv, integ)
        ifd["dv_after_dv"], ifd["dimpulse_dv"] = central_differences(lambda x: g(q, x), v, model.nv, add)
        M = pin.crba(model, model.createData(), q)
        M = np.triu(M) + np.triu(M, 1).T
        checks["impulse"] = {"J_v_after": float(np.abs(J @ vplus).max()),
                             "momentum_residual": float(np.abs(M @ (vplus - v) - J.T @ imp).max()),
                             "fd": {k: rel_err(ider[k], ifd[k]) for k in IMPULSE_DERIVS}}
        s["impulse"] = {"restitution": 0.0, "v_after": vplus, "impulse": imp, **ider}
    return s, checks


# ------------------------------------------------------------------ cases and output

def se3(M):
    return {"rotation": M.rotation.tolist(), "translation": M.translation.tolist()}


def plain(x):
    """numpy -> lists (matrices as lists of rows) of Python floats, recursively."""
    if isinstance(x, dict):
        return {k: plain(v) for k, v in x.items()}
    if isinstance(x, np.ndarray):
        assert np.all(np.isfinite(x))
        return x.tolist()
    return x


def describe(model, cons, case):
    joints = []
    for j in range(1, model.njoints):
        jm = model.joints[j]
        entry = {"name": model.names[j], "type": jm.shortname(), "parent": model.names[model.parents[j]],
                 "idx_q": jm.idx_q, "idx_v": jm.idx_v, "nq": jm.nq, "nv": jm.nv}
        if case.startswith("fourbar"):  # built in code: give what it takes to rebuild it
            Y = model.inertias[j]
            entry.update(placement=se3(model.jointPlacements[j]),
                         inertia={"mass": Y.mass, "lever": Y.lever.tolist(), "rotational_inertia": Y.inertia.tolist()})
        joints.append(entry)
    constraints = []
    for frame, ctype, ref, j1, m1, j2, m2 in cons:
        c = {"type": "CONTACT_6D" if ctype == C6D else "CONTACT_3D",
             "reference_frame": "LOCAL" if ref == LOCAL else "LOCAL_WORLD_ALIGNED",
             "size": 6 if ctype == C6D else 3,
             "joint1_name": model.names[j1], "joint1_placement": se3(m1), "joint2_name": model.names[j2]}
        if frame is not None:
            c["frame"] = frame
            c["joint2_placement"] = "the frame's world placement at the sample's q (enters no output: gains 0)"
        else:
            c["joint2_placement"] = se3(m2)
        constraints.append(c)
    return joints, constraints


def run_case(index, case):
    model, cons, settings, desc, src = build(case)
    rng = np.random.default_rng(SEED + index)
    with_impulse = case == "solo12_4feet_lwa"
    samples, allchecks, redrawn = [], [], 0
    while len(samples) < N_SAMPLES:
        if case.startswith("fourbar"):
            q, v, tau = closed_state(model, cons, settings, case == "fourbar_branch", rng)
        else:
            q, v, tau = random_state(model, rng)
        J = forward(model, constraint_models(model, cons, q), settings, q, v, tau)[2]
        if smallest_singular_value(J) < SIGMA_MIN:
            redrawn += 1
            continue
        s, checks = evaluate(case, model, cons, settings, q, v, tau, with_impulse)
        samples.append(plain(s))
        allchecks.append(checks)

    worst = lambda get: max(get(c) for c in allchecks)
    sanity = {k: worst(lambda c: c[k]) for k in ("J_ddq_plus_gamma", "fk_constraint_acceleration", "eom_residual")}
    sanity["sigma_min_J"] = min(c["sigma_min_J"] for c in allchecks)
    sanity["iterations"] = sorted({c["iterations"] for c in allchecks})
    sanity["redrawn"] = redrawn
    sanity["fd_rel_err"] = {k: worst(lambda c: c["fd"][k]) for k in DERIVS}
    warnings = [f"{k}: computeConstraintDynamicsDerivatives differs from central differences "
                f"(max relative error {e:.2g})" + (f"; see {k}_fd" if case == "fourbar_branch" else "")
                for k, e in sanity["fd_rel_err"].items() if e > FLAG]
    if with_impulse:
        sanity["impulse"] = {k: worst(lambda c: c["impulse"][k]) for k in ("J_v_after", "momentum_residual")}
        sanity["impulse"]["fd_rel_err"] = {k: worst(lambda c: c["impulse"]["fd"][k]) for k in IMPULSE_DERIVS}
        warnings += [f"impulse {k}: differs from central differences (max relative error {e:.2g})"
                     for k, e in sanity["impulse"]["fd_rel_err"].items() if e > FLAG]
    joints, constraints = describe(model, cons, case)
    return {"description": desc, "model": src, "seed": SEED + index, "nq": model.nq, "nv": model.nv,
            "nc": sum(c["size"] for c in constraints), "gravity": model.gravity.linear.tolist(),
            "joints": joints, "constraints": constraints, "baumgarte": {"Kp": 0.0, "Kd": 0.0},
            "proximal": dict(zip(["absolute_accuracy", "relative_accuracy", "mu", "max_iter"], settings)),
            "sanity": sanity, "warnings": warnings, "samples": samples}


def main():
    assert pin.__version__ == "4.1.0", pin.__version__
    out = {"generator": "tests/data/constrained/reference.py", "pinocchio": pin.__version__,
           "numpy": np.__version__, "fd_eps": EPS, "fd_flag": FLAG, "cases": {}}
    for i, case in enumerate(CASES):
        out["cases"][case] = run_case(i, case)
        print(case, json.dumps(out["cases"][case]["sanity"]), *out["cases"][case]["warnings"], sep="\n  ")
    # one level of indentation: each top-level key, and each case, on its own line
    lines = [f"  {json.dumps(k)}: {json.dumps(v)}" for k, v in out.items() if k != "cases"]
    cases = ",\n".join(f"    {json.dumps(k)}: {json.dumps(v, separators=(',', ':'))}"
                       for k, v in out["cases"].items())
    with open(OUT, "w") as fh:
        fh.write("{\n" + ",\n".join(lines) + ',\n  "cases": {\n' + cases + "\n  }\n}\n")


if __name__ == "__main__":
    main()
