//! The references: closed forms of the uncoupled neo-Hookean law
//! `W = mu / 2 (J^(-2/3) I1 - 3) + kappa / 4 (J^2 - 1 - 2 ln J)` (FEBio's; docs/fem.md) under
//! homogeneous deformations, the incompressible thick sphere and cylinder (Ogden), Hertz's contact
//! (Johnson) and the elastica (a shooting solution of its ordinary differential equation).
//! None of them calls the finite-element code.

/// Bisection steps: enough for f64 on every bracket used here.
const BISECTIONS: usize = 200;

/// The root of an increasing `f` in `[lo, hi]` by bisection.
fn increasing_root(f: impl Fn(f64) -> f64, (mut lo, mut hi): (f64, f64)) -> f64 {
    for _ in 0..BISECTIONS {
        let mid = 0.5 * (lo + hi);
        if f(mid) < 0.0 { lo = mid } else { hi = mid }
    }
    0.5 * (lo + hi)
}

/// The nominal (first Piola–Kirchhoff) principal stresses `dW / d lambda_i` (Pa) of the
/// neo-Hookean law at principal stretches `l`:
/// `mu J^(-2/3) (l_i - I1 / (3 l_i)) + kappa / 2 (J^2 - 1) / l_i`.
pub fn principal_nominal_stress(mu: f64, kappa: f64, l: [f64; 3]) -> [f64; 3] {
    let j = l[0] * l[1] * l[2];
    let i1 = l.iter().map(|x| x * x).sum::<f64>();
    l.map(|li| mu * j.powf(-2.0 / 3.0) * (li - i1 / (3.0 * li)) + 0.5 * kappa * (j * j - 1.0) / li)
}

/// The stretch along the loaded axes of a block pulled by the nominal stress `p` (Pa) on
/// `loaded` of its three axes (1: uniaxial, 2: equibiaxial), the other axes free of stress.
pub fn stretch_under_nominal_stress(mu: f64, kappa: f64, loaded: usize, p: f64) -> f64 {
    let free_stretch = |l: f64| {
        let stress = |s: f64| {
            let mut ls = [s; 3];
            ls[..loaded].fill(l);
            principal_nominal_stress(mu, kappa, ls)[2]
        };
        increasing_root(stress, (0.05, 20.0))
    };
    let loaded_stress = |l: f64| {
        let s = free_stretch(l);
        let mut ls = [s; 3];
        ls[..loaded].fill(l);
        principal_nominal_stress(mu, kappa, ls)[0] - p
    };
    increasing_root(loaded_stress, (0.2, 5.0))
}

/// Simple shear `x += gamma y`: the shear stress `sigma_xy = P_xy = mu gamma` (Pa; `J = 1`,
/// so the volumetric part vanishes and the isochoric one is linear in gamma).
pub fn simple_shear_stress(mu: f64, gamma: f64) -> f64 {
    mu * gamma
}

/// The incompressible neo-Hookean thick sphere (inner radius `a`, outer `b`) under an inner
/// pressure, as a function of the inner stretch `la` (Ogden, Non-linear Elastic
/// Deformations, 1984, §5.3): `p = mu (2/lb + 1/(2 lb^4) - 2/la - 1/(2 la^4))`, with
/// `lb^3 = 1 + (la^3 - 1) a^3 / b^3`.
pub fn thick_sphere_pressure(mu: f64, la: f64, a: f64, b: f64) -> f64 {
    let lb = (1.0 + (la.powi(3) - 1.0) * (a / b).powi(3)).cbrt();
    mu * (2.0 / lb + 0.5 / lb.powi(4) - 2.0 / la - 0.5 / la.powi(4))
}

/// The inner stretch at the largest pressure the thick sphere holds (its limit point).
pub fn thick_sphere_limit_stretch(a: f64, b: f64) -> f64 {
    // The pressure rises, then falls: bisect its slope.
    let slope = |la: f64| {
        let d = 1e-6;
        thick_sphere_pressure(1.0, la - d, a, b) - thick_sphere_pressure(1.0, la + d, a, b)
    };
    increasing_root(slope, (1.05, 4.0))
}

/// The inner stretch of the thick sphere at inner pressure `p` (on the rising branch, below
/// the limit point).
pub fn thick_sphere_stretch(mu: f64, p: f64, a: f64, b: f64) -> f64 {
    let top = thick_sphere_limit_stretch(a, b);
    increasing_root(|la| thick_sphere_pressure(mu, la, a, b) - p, (1.0, top))
}

/// The incompressible neo-Hookean thick cylinder in plane strain (inner radius `a`, outer
/// `b`, no axial stretch) under an inner pressure, as a function of the inner stretch `la`
/// (Ogden, Non-linear Elastic Deformations, 1984, §5.3; the integral of
/// `mu (l^2 - l^-2) dr / r` across the wall): `p = mu (ln(la / lb) + (1/lb^2 - 1/la^2) / 2)`,
/// with `lb^2 = 1 + (la^2 - 1) a^2 / b^2`. It rises monotonically towards `mu ln(b / a)`: no
/// limit point.
pub fn thick_cylinder_pressure(mu: f64, la: f64, a: f64, b: f64) -> f64 {
    let lb2 = 1.0 + (la * la - 1.0) * (a / b).powi(2);
    mu * (0.5 * (la * la / lb2).ln() + 0.5 * (1.0 / lb2 - 1.0 / (la * la)))
}

/// Hertz: the force (N) pressing a linear elastic sphere of radius `r` between two rigid
/// frictionless plates that each approach its centre by `depth` (m):
/// `F = 4/3 E* sqrt(r) depth^(3/2)`, `E* = E / (1 - nu^2)` (Johnson, Contact Mechanics, 1985,
/// §4.2; each contact alone).
pub fn hertz_force(young: f64, poisson: f64, r: f64, depth: f64) -> f64 {
    4.0 / 3.0 * young / (1.0 - poisson * poisson) * r.sqrt() * depth.powf(1.5)
}

/// The elastica: a cantilever of length 1 clamped at one end, under a dead transverse load
/// at the other with `alpha = P L^2 / (E I)`. Its slope `theta(s)` satisfies
/// `theta'' = -alpha cos(theta)`, `theta(0) = 0`, `theta'(1) = 0`; shot on `theta'(0)` with
/// RK4 (4000 steps). Returns the tip's deflection along the load and its shortening along
/// the beam, both over the length.
pub fn elastica_tip(alpha: f64) -> [f64; 2] {
    let moment_at_tip = |k0: f64| integrate_elastica(alpha, k0).2;
    let k0 = increasing_root(moment_at_tip, (0.0, alpha));
    let (x, y, _) = integrate_elastica(alpha, k0);
    [y, 1.0 - x]
}

/// Integrates the elastica from the clamp with `theta'(0) = k0`: the tip's `(x, y)` and
/// `theta'(1)`.
fn integrate_elastica(alpha: f64, k0: f64) -> (f64, f64, f64) {
    const STEPS: usize = 4000;
    let h = 1.0 / STEPS as f64;
    // State: theta, theta', x, y.
    let rate = |s: [f64; 4]| [s[1], -alpha * s[0].cos(), s[0].cos(), s[0].sin()];
    let mut s = [0.0, k0, 0.0, 0.0];
    for _ in 0..STEPS {
        let add = |a: [f64; 4], b: [f64; 4], f: f64| std::array::from_fn::<f64, 4, _>(|i| a[i] + f * b[i]);
        let k1 = rate(s);
        let k2 = rate(add(s, k1, 0.5 * h));
        let k3 = rate(add(s, k2, 0.5 * h));
        let k4 = rate(add(s, k3, h));
        s = std::array::from_fn(|i| s[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]));
    }
    (s[2], s[3], s[1])
}
