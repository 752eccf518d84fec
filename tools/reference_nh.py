#!/usr/bin/env python3
"""Independent neo-Hookean reference for fibfluid-fem: quadratic tetrahedra (P2), Newton's
method with load stepping.

The energy is fibfluid's (docs/fem.md, "Large deformation: the neo-Hookean tissue"): the
uncoupled compressible neo-Hookean solid of FEBio (Maas, Ellis, Ateshian and Weiss, J Biomech
Eng 134:011005, 2012; the split of Simo and Taylor, CMAME 85:273, 1991), total Lagrangian,

    W(F) = mu / 2 (J^(-2/3) I1 - 3) + kappa / 4 (J^2 - 1 - 2 ln J),   I1 = F : F,  J = det F,
    mu = E / (2 (1 + nu)),   kappa = E / (3 (1 - 2 nu)),

per unit rest volume, with dead loads (gravity `rho g` per unit rest volume). Unlike
fibfluid (hexahedra on a sparse grid, mean dilatation per cell, the surface embedded), the
volumetric term is integrated pointwise like the rest: P2 tetrahedra, 4th-order quadrature
(11 points), on a TetGen mesh of the surface itself.

First Piola-Kirchhoff stress and its derivative (G = F^-T):

    P = mu J^(-2/3) (F - I1/3 G) + kappa / 2 (J^2 - 1) G
    dP[H] = mu J^(-2/3) (H - 2/3 (G:H) F - 2/3 (F:H) G + 2/9 I1 (G:H) G + I1/3 G H^T G)
          + kappa (J^2 (G:H) G - (J^2 - 1) / 2 G H^T G)

Residual r(u) = int P : grad v - t f, tangent its derivative, both assembled here (numpy,
vectorized over elements and quadrature points) on scikit-fem's scalar P2 basis (shape
gradients, quadrature weights, element dofs). Vector dof `3 s + c` is component `c` of
scalar dof `s`.

Newton's method: K du = -r (conjugate gradients preconditioned by pyamg's smoothed
aggregation on the six rigid-body modes, or SuperLU), backtracking line search on the
energy (Armijo 1e-4; a step that lowers the residual is taken when the energy no longer
resolves progress); converged when |r| <= tol |t f| (tol 1e-8) on the free dofs. Load
factor t from 0 to 1 in equal increments; a step that fails (30 iterations, an inverted
element, a CG failure) is halved, one that converges within 6 iterations doubles the next;
each step starts from the last one extrapolated (secant predictor).

`python3 reference_nh.py --verify` checks the implementation: the unit cube in uniaxial
stress against the closed form, the residual and the tangent against central differences
of the energy and of the residual. The surface reference runs through reference.py:
`reference.py ... --model neo-hookean`.
"""
import sys
import time

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import LinearOperator, cg, spsolve
from skfem import Basis, ElementTetP2, LinearForm, asm


def moduli(young, poisson):
    return young / (2 * (1 + poisson)), young / (3 * (1 - 2 * poisson))


def kinematics(F):
    """J, ln J, F^-T, I1 at every point; F has shape (..., 3, 3)."""
    J = np.linalg.det(F)
    G = np.swapaxes(np.linalg.inv(F), -1, -2)
    I1 = np.einsum("...ij,...ij->...", F, F)
    return J, G, I1


def energy_density(F, mu, kappa):
    if np.any(np.linalg.det(F) <= 0):
        return None
    J, _, I1 = kinematics(F)
    return mu / 2 * (J ** (-2 / 3) * I1 - 3) + kappa / 4 * (J**2 - 1 - 2 * np.log(J))


def stress(F, mu, kappa):
    """First Piola-Kirchhoff stress."""
    J, G, I1 = kinematics(F)
    a = (mu * J ** (-2 / 3))[..., None, None]
    return a * (F - I1[..., None, None] / 3 * G) + (kappa / 2 * (J**2 - 1))[..., None, None] * G


def tangent(F, mu, kappa):
    """A[..., i, j, k, l] = dP_ij / dF_kl."""
    J, G, I1 = kinematics(F)
    J2 = (J**2)[..., None, None, None, None]
    a = mu * J ** (-2 / 3)
    eye = np.eye(3)
    I1 = I1[..., None, None, None, None]
    GG = np.einsum("...ij,...kl->...ijkl", G, G)          # G_ij G_kl
    GxG = np.einsum("...il,...kj->...ijkl", G, G)         # G_il G_kj
    A = np.broadcast_to(np.einsum("ik,jl->ijkl", eye, eye), GG.shape).copy()
    A -= 2 / 3 * (np.einsum("...ij,...kl->...ijkl", F, G) + np.einsum("...ij,...kl->...ijkl", G, F))
    A += 2 / 9 * I1 * GG + I1 / 3 * GxG
    A *= a[..., None, None, None, None]
    A += kappa * (J2 * GG - (J2 - 1) / 2 * GxG)
    return A


class Body:
    """P2 displacement on a MeshTet; dofs 3 s + c."""

    def __init__(self, mesh, young, poisson, intorder=4):
        self.mesh = mesh
        self.mu, self.kappa = moduli(young, poisson)
        sb = Basis(mesh, ElementTetP2(), intorder=intorder)
        self.sb = sb
        self.N = 3 * sb.N
        # (nel, nqp, 10, 3) shape gradients, (nel, nqp) weights, (nel, 10) scalar dofs
        self.G = np.stack([sb.basis[a][0].grad for a in range(sb.Nbfun)], axis=0).transpose(2, 3, 0, 1).copy()
        self.dx = np.asarray(sb.dx)
        self.edofs = sb.element_dofs.T.copy()
        vd = (3 * self.edofs[:, :, None] + np.arange(3)).reshape(len(self.edofs), -1)  # (nel, 30)
        self.vdofs = vd
        self.rows = np.repeat(vd, 30, axis=1).ravel()
        self.cols = np.tile(vd, (1, 30)).ravel()

        @LinearForm
        def one(v, w):
            return v

        self.mass = asm(one, sb)  # int N_s

    def load(self, body_force):
        """Dead load of a constant force per unit rest volume."""
        f = np.zeros(self.N)
        for c in range(3):
            f[c::3] = body_force[c] * self.mass
        return f

    def grad(self, u):
        ue = u.reshape(-1, 3)[self.edofs]  # (nel, 10, 3)
        return np.eye(3) + np.einsum("eai,eqaj->eqij", ue, self.G)

    def energy(self, u):
        W = energy_density(self.grad(u), self.mu, self.kappa)
        return None if W is None else float(np.sum(W * self.dx))

    def internal(self, u):
        P = stress(self.grad(u), self.mu, self.kappa) * self.dx[..., None, None]
        fe = np.einsum("eqij,eqaj->eai", P, self.G).reshape(len(self.edofs), -1)
        return np.bincount(self.vdofs.ravel(), fe.ravel(), minlength=self.N)

    def stiffness(self, u, chunk=3000):
        F = self.grad(u)
        data = np.empty((len(self.edofs), 30, 30))
        for s in range(0, len(self.edofs), chunk):
            e = slice(s, s + chunk)
            A = tangent(F[e], self.mu, self.kappa)
            Gw = self.G[e] * self.dx[e][..., None, None]
            T = np.einsum("eqaj,eqijkl->eqaikl", Gw, A, optimize=True)
            Ke = np.einsum("eqaikl,eqbl->eaibk", T, self.G[e], optimize=True)
            data[e] = Ke.reshape(-1, 30, 30)
        K = sp.coo_matrix((data.ravel(), (self.rows, self.cols)), shape=(self.N, self.N)).tocsr()
        return K

    def vector_dofs(self, scalar_dofs, components=(0, 1, 2)):
        s = np.asarray(scalar_dofs, dtype=int)
        return np.unique((3 * s[:, None] + np.array(components)).ravel())

    def nodal(self, u):
        """(nvertices, 3) displacement at the mesh vertices."""
        return u.reshape(-1, 3)[self.sb.nodal_dofs[0]]

    def rigid_modes(self):
        x = self.sb.doflocs  # (3, Ns)
        x = x - x.mean(axis=1, keepdims=True)
        B = np.zeros((self.N, 6))
        for c in range(3):
            B[c::3, c] = 1.0
        for k, (i, j) in enumerate([(1, 2), (2, 0), (0, 1)]):
            B[i::3, 3 + k] = -x[j]
            B[j::3, 3 + k] = x[i]
        return B


def linear_solve(A, b, solver, modes, rtol):
    if solver == "direct":
        return spsolve(A.tocsc(), b), 0
    if solver == "amg":
        import pyamg

        ml = pyamg.smoothed_aggregation_solver(A, B=modes, symmetry="hermitian")
        M = ml.aspreconditioner(cycle="V")
    else:
        d = 1.0 / A.diagonal()
        M = LinearOperator(A.shape, lambda r: d * r)
    its = [0]

    def count(_):
        its[0] += 1

    x, info = cg(A, b, rtol=rtol, maxiter=5000 if solver == "amg" else 100000, M=M, callback=count)
    if info != 0:
        return None, its[0]
    return x, its[0]


def newton_solve(body, f, D, uD=None, steps=4, tol=1e-8, solver="amg", max_iter=30, log=print):
    """Equilibrium of body under t f (t up to 1), dofs D held at t uD (0 when None).
    Returns u and the list of (t, iterations, residual history)."""
    N = body.N
    free = np.setdiff1d(np.arange(N), D)
    uD = np.zeros(len(D)) if uD is None else np.asarray(uD, dtype=float)
    modes = body.rigid_modes()[free] if solver == "amg" else None
    u = np.zeros(N)
    u_prev, dt_prev = None, None
    t, dt = 0.0, 1.0 / steps
    history = []
    while t < 1 - 1e-14:
        dt = min(dt, 1 - t)
        t_new = t + dt
        if np.any(uD):
            u0 = held_predictor(body, u, D, t_new * uD, free, solver, modes)
        else:
            u0 = u.copy() if u_prev is None else u + dt / dt_prev * (u - u_prev)
            u0[D] = 0.0
            if body.energy(u0) is None:
                u0 = u.copy()
        ok, v, hist = newton(body, u0, t_new * f, free, tol, solver, modes, max_iter, log)
        if ok:
            u_prev, dt_prev, u = u, dt, v
            t = t_new
            history.append((t, len(hist) - 1, hist))
            log("  load %.4f: %d Newton iterations, residuals %s"
                % (t, len(hist) - 1, " ".join("%.1e" % h for h in hist)))
            if len(hist) - 1 <= 6:
                dt *= 2
        else:
            dt /= 2
            log("  load %.4f failed (%s); increment %.4g" % (t_new, hist, dt))
            if dt < 1e-4:
                raise RuntimeError("Newton's method did not converge at load %.4f" % t_new)
    return u, history


def held_predictor(body, u, D, uD_new, free, solver, modes):
    """`u` with the held dofs `D` moved to `uD_new` and that motion carried into the free
    dofs by the tangent at `u` (the first Newton iterate of a displacement-driven step); `u`
    with only the held dofs moved when that inverts an element or CG fails."""
    v = u.copy()
    du = uD_new - u[D]
    K = body.stiffness(u)
    d, _ = linear_solve(K[free][:, free], -(K[free][:, D] @ du), solver, modes, 1e-10)
    if d is not None:
        v[free] += d
    v[D] = uD_new
    if body.energy(v) is None:
        v = u.copy()
        v[D] = uD_new
    return v


def contact_solve(body, f, D0, plates, steps=8, tol=1e-8, solver="amg", max_iter=30, log=print):
    """Equilibrium under t f with dofs D0 held at 0 and frictionless rigid plates, each
    `(axis, sign, position, travel)`: the plane `x[axis] = position + sign t travel`, the
    body on the side `sign (x[axis] - plane) >= 0`. Contact is an active set on the P2
    nodes of the boundary: a node past a plate has its normal component held on the plane;
    a held node whose reaction pulls the plate (below -RELEASE of the largest reaction) is
    let go; each load step repeats until the set is stable. Returns u, the history and the
    plates' forces on the body along their normals (the sum of the held nodes' reactions)."""
    RELEASE = 1e-2
    X = body.sb.doflocs.T  # (Ns, 3) scalar dof positions
    on_boundary = np.zeros(body.sb.N, dtype=bool)
    on_boundary[body.sb.get_dofs(body.mesh.boundary_facets()).all()] = True
    all_modes = body.rigid_modes() if solver == "amg" else None
    D0 = np.asarray(D0, dtype=int)
    held0 = np.zeros(body.N, dtype=bool)
    held0[D0] = True
    size = np.ptp(X, axis=0).max()
    active = [np.zeros(body.sb.N, dtype=bool) for _ in plates]
    u = np.zeros(body.N)
    t, dt, history = 0.0, 1.0 / steps, []
    while t < 1 - 1e-14:
        dt = min(dt, 1 - t)
        t_new, ok, current = t + dt, False, u
        settled = [a.copy() for a in active]
        for sweep in range(40):
            held, values = [D0], [np.zeros(len(D0))]
            for (axis, sign, position, travel), on in zip(plates, active):
                s = np.flatnonzero(on)
                held.append(3 * s + axis)
                values.append(position + sign * t_new * travel - X[s, axis])
            D = np.concatenate(held)
            order = np.argsort(D)
            D, uD = D[order], np.concatenate(values)[order]
            free = np.setdiff1d(np.arange(body.N), D)
            modes = None if all_modes is None else all_modes[free]
            u0 = held_predictor(body, current, D, uD, free, solver, modes)
            ok, v, hist = newton(body, u0, t_new * f, free, tol, solver, modes, max_iter, log)
            if not ok:
                break
            r = body.internal(v) - t_new * f
            changed = False
            reactions = []
            for (axis, sign, position, travel), on in zip(plates, active):
                x = X[:, axis] + v[axis::3]
                gap = sign * (x - (position + sign * t_new * travel))
                past = ~on & ~held0[axis::3] & on_boundary & (gap < -1e-9 * size)
                reaction = sign * r[axis::3]  # the plate's push on the body, along its normal
                largest = max(np.abs(reaction[on]).max(initial=0.0), 1e-300)
                pulls = on & (reaction < -RELEASE * largest)
                if past.any() or pulls.any():
                    changed = True
                on |= past
                on &= ~pulls
                reactions.append(reaction[on].sum())
            current = v
            if not changed:
                break
            log("  load %.4f, sweep %d: contact set changed (%s nodes)"
                % (t_new, sweep, ", ".join(str(int(a.sum())) for a in active)))
        if ok and not changed:
            u, t = v, t_new
            history.append((t, len(hist) - 1, hist))
            log("  load %.4f: %d Newton iterations (last sweep), plate forces %s N, nodes in contact %s"
                % (t, len(hist) - 1, " ".join("%.6g" % x for x in reactions),
                   " ".join(str(int(a.sum())) for a in active)))
        else:
            active = settled
            dt /= 2
            log("  load %.4f failed (%s); increment %.4g" % (t_new, hist if not ok else "contact set", dt))
            if dt < 1e-4:
                raise RuntimeError("the contact solve did not converge at load %.4f" % t_new)
    return u, history, reactions


def newton(body, u, f, free, tol, solver, modes, max_iter, log):
    fnorm = np.linalg.norm(f[free])

    def total(v):
        e = body.energy(v)
        return None if e is None else e - f @ v

    if total(u) is None:
        return False, u, "inverted element"
    fint = body.internal(u)
    r = fint - f
    # relative to the load or, under held dofs alone, to the internal forces (reactions)
    scale = max(fnorm, np.linalg.norm(fint), 1e-300)
    hist = [np.linalg.norm(r[free]) / scale]
    Pi = total(u)
    for it in range(max_iter):
        if hist[-1] <= tol:
            return True, u, hist
        K = body.stiffness(u)[free][:, free]
        # CG to well below the current residual (inexact Newton, quadratic to the end)
        rtol = max(1e-12, min(1e-4, 1e-3 * hist[-1]))
        d, its = linear_solve(K, -r[free], solver, modes, rtol)
        if d is None:
            return False, u, "CG did not converge"
        step = np.zeros_like(u)
        step[free] = d
        slope = r[free] @ d
        alpha = 1.0
        while True:
            v = u + alpha * step
            Pv = total(v)
            if Pv is not None:
                if Pv <= Pi + 1e-4 * alpha * slope:
                    break
                rv = body.internal(v) - f
                # near the solution the energy no longer resolves progress
                if abs(Pv - Pi) <= 1e-12 * abs(Pi) and np.linalg.norm(rv[free]) < hist[-1] * scale:
                    break
            alpha /= 2
            if alpha < 1e-4:
                return False, u, "no descent"
        u, Pi = v, Pv
        fint = body.internal(u)
        r = fint - f
        scale = max(fnorm, np.linalg.norm(fint), 1e-300)
        hist.append(np.linalg.norm(r[free]) / scale)
    return hist[-1] <= tol, u, hist if hist[-1] <= tol else "%d iterations" % max_iter


# ----------------------------------------------------------------------------------------
# Verification


def uniaxial_closed_form(stretch, mu, kappa):
    """Uniaxial stress F = diag(l, s, s): s solves dW/ds = 0; returns (nominal stress
    dW/dl, s)."""
    from scipy.optimize import brentq

    def P(l, s):
        F = np.diag([l, s, s])
        return stress(F, mu, kappa)

    s = brentq(lambda s: P(stretch, s)[1, 1], 0.2, 5.0, xtol=1e-15)
    return P(stretch, s)[0, 0], s


def verify():
    from skfem import MeshTet

    young, poisson = 5000.0, 0.45
    mesh = MeshTet.init_tensor(*[np.linspace(0, 1, 4)] * 3)
    body = Body(mesh, young, poisson)
    x = body.sb.doflocs
    ok = True
    print("unit cube, %d P2 dofs, E = %g, nu = %g (mu %.3f, kappa %.3f)"
          % (body.N, young, poisson, body.mu, body.kappa))
    # symmetry planes x = 0, y = 0, z = 0; x = 1 pushed to the stretch
    on = lambda c, v: np.flatnonzero(np.abs(x[c] - v) < 1e-12)
    for stretch in (0.9, 0.7, 0.5, 1.3):
        D = np.concatenate([3 * on(0, 0) + 0, 3 * on(1, 0) + 1, 3 * on(2, 0) + 2, 3 * on(0, 1) + 0])
        uD = np.concatenate([np.zeros(len(on(0, 0)) + len(on(1, 0)) + len(on(2, 0))),
                             np.full(len(on(0, 1)), stretch - 1)])
        D, idx = np.unique(D, return_index=True)
        uD = uD[idx]
        t0 = time.time()
        u, hist = newton_solve(body, np.zeros(body.N), D, uD, steps=2, solver="direct", log=lambda s: None)
        fint = body.internal(u)
        force = fint[3 * on(0, 1) + 0].sum()  # reaction on x = 1, area 1: nominal stress
        lateral = 1 + u[3 * on(1, 1) + 1].mean()
        P11, s = uniaxial_closed_form(stretch, body.mu, body.kappa)
        e1, e2 = force / P11 - 1, lateral / s - 1
        ok &= abs(e1) < 1e-6 and abs(e2) < 1e-6
        print("  stretch %.1f: nominal stress %.6f Pa (closed form %.6f, %+.1e), lateral stretch %.7f"
              " (%.7f, %+.1e); %d steps, %s Newton iterations, %.1f s"
              % (stretch, force, P11, e1, lateral, s, e2, len(hist), [h[1] for h in hist], time.time() - t0))

    # the same compression by a frictionless plate on x = 1 (contact_solve's active set)
    for stretch in (0.7, 0.5):
        D = np.unique(np.concatenate([3 * on(0, 0) + 0, 3 * on(1, 0) + 1, 3 * on(2, 0) + 2]))
        t0 = time.time()
        u, hist, forces = contact_solve(body, np.zeros(body.N), D, [(0, -1.0, 1.0, 1 - stretch)], steps=2,
                                        solver="direct", log=lambda s: None)
        lateral = 1 + u[3 * on(1, 1) + 1].mean()
        P11, s = uniaxial_closed_form(stretch, body.mu, body.kappa)
        e1, e2 = -forces[0] / P11 - 1, lateral / s - 1
        ok &= abs(e1) < 1e-6 and abs(e2) < 1e-6
        print("  plate to stretch %.1f: force %.6f N (closed form %.6f, %+.1e), lateral stretch %.7f"
              " (%.7f, %+.1e); %d steps, %.1f s"
              % (stretch, forces[0], -P11, e1, lateral, s, e2, len(hist), time.time() - t0))

    # residual and tangent against central differences, at a random finite strain
    rng = np.random.default_rng(1)
    mesh = MeshTet.init_tensor(*[np.linspace(0, 1, 3)] * 3)
    body = Body(mesh, young, poisson)
    x = body.sb.doflocs
    u = np.zeros(body.N)
    for c in range(3):  # a smooth finite deformation plus noise
        u[c::3] = 0.2 * np.sin(1.3 * x[c] + 0.7 * x[(c + 1) % 3]) + 0.02 * rng.standard_normal(x.shape[1])
    assert np.all(np.linalg.det(body.grad(u)) > 0)
    r, K = body.internal(u), body.stiffness(u)
    v = rng.standard_normal(body.N)
    h = 1e-5
    dE = (body.energy(u + h * v) - body.energy(u - h * v)) / (2 * h)
    dr = (body.internal(u + h * v) - body.internal(u - h * v)) / (2 * h)
    eg = abs(dE - r @ v) / abs(r @ v)
    eh = np.linalg.norm(dr - K @ v) / np.linalg.norm(K @ v)
    es = abs(K - K.T).max() / abs(K).max()
    ok &= eg < 1e-7 and eh < 1e-7 and es < 1e-12
    print("finite differences (h = %g, %d dofs, max |grad u| %.2f): gradient %.1e, tangent %.1e, "
          "asymmetry %.1e" % (h, body.N, np.abs(body.grad(u) - np.eye(3)).max(), eg, eh, es))
    # small strain: the tangent at u = 0 is linear elasticity with the same E, nu
    from skfem import ElementVector
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    vb = Basis(mesh, ElementVector(ElementTetP2()), intorder=4)
    KL = asm(linear_elasticity(*lame_parameters(young, poisson)), vb)
    # skfem orders the vector dofs differently: compare energies of the same field
    K0 = body.stiffness(np.zeros(body.N))
    w = np.zeros(vb.N)
    for c in range(3):
        w[vb.nodal_dofs[c]] = v[3 * body.sb.nodal_dofs[0] + c]
        w[vb.edge_dofs[c]] = v[3 * body.sb.edge_dofs[0] + c]
    el = abs(v @ K0 @ v / (w @ KL @ w) - 1)
    ok &= el < 1e-12
    print("tangent at rest against scikit-fem's linear elasticity (same E, nu): %.1e" % el)
    print("OK" if ok else "FAILED")
    return ok


if __name__ == "__main__":
    if "--verify" in sys.argv:
        sys.exit(0 if verify() else 1)
    print(__doc__)
