//! CBR bounds against numbers derived by hand from Eq. 2, 3 and 4 of the paper, and
//! parameter validation.

use fibfluid_chainmail::{ChainmailError, GeneralizedMaterial, Material, TsveMaterial};

fn close(a: [f64; 3], b: [f64; 3]) {
    for k in 0..3 {
        assert!((a[k] - b[k]).abs() < 1e-12, "{a:?} != {b:?}");
    }
}

/// Eq. 2 with alpha_min 0.8, alpha_max 1.3, beta 0.1 and rest offset d = (2, -1, 0.5):
/// x: 0.8*2 - 0.1*(1 + 0.5) = 1.45, 1.3*2 + 0.15 = 2.75;
/// y (neighbour on the -y side, mirrored): -1.3 - 0.1*2.5 = -1.55, -0.8 + 0.25 = -0.55;
/// z: 0.8*0.5 - 0.1*3 = 0.1, 1.3*0.5 + 0.3 = 0.95.
#[test]
fn generalized_bounds_by_hand() {
    let m = GeneralizedMaterial::isotropic(0.8, 1.3, 0.1);
    let c = m.cbr(0, 1, [2.0, -1.0, 0.5]).unwrap();
    close(c.min, [1.45, -1.55, 0.1]);
    close(c.max, [2.75, -0.55, 0.95]);
}

/// Per-axis Generalized parameters: only the axis-a parameters enter the axis-a limits.
/// Face link d = (0, 0, 1): x in [-beta_x, beta_x] = [-0.2, 0.2], y in [-0.3, 0.3],
/// z in [alpha_min_z, alpha_max_z] = [0.6, 1.1].
#[test]
fn generalized_per_axis_by_hand() {
    let m =
        GeneralizedMaterial { alpha_min: [0.9, 0.8, 0.6], alpha_max: [1.5, 1.4, 1.1], beta: [0.2, 0.3, 0.4] };
    let c = m.cbr(3, 4, [0.0, 0.0, 1.0]).unwrap();
    close(c.min, [-0.2, -0.3, 0.6]);
    close(c.max, [0.2, 0.3, 1.1]);
}

/// Eq. 3 with alpha_i 0.2, alpha_j 0.4 (mean 0.3) and d = (2, -1, 0.5), L1 = 3.5, so the
/// half-width is 1.05: x in [0.95, 3.05], y in [-2.05, 0.05], z in [-0.55, 1.55].
#[test]
fn tsve_heterogeneous_bounds_by_hand() {
    let m = TsveMaterial::heterogeneous(&[0.2, 0.4]);
    let c = m.cbr(0, 1, [2.0, -1.0, 0.5]).unwrap();
    close(c.min, [0.95, -2.05, -0.55]);
    close(c.max, [3.05, 0.05, 1.55]);
    // Swapping i and j does not change the (symmetric) mean parameter.
    let c2 = m.cbr(1, 0, [2.0, -1.0, 0.5]).unwrap();
    close(c2.min, c.min);
}

/// Eq. 4 (isotropic alpha = 0.3, d = (2, 1, 0.5)):
/// x_min = (1 - 0.3)*2 - 0.3*(1 + 0.5) = 0.95, x_max = 1.3*2 + 0.45 = 3.05;
/// y_min = 0.7*1 - 0.3*2.5 = -0.05, y_max = 1.3 + 0.75 = 2.05;
/// z_min = 0.7*0.5 - 0.3*3 = -0.55, z_max = 0.65 + 0.9 = 1.55.
#[test]
fn tsve_isotropic_matches_eq4() {
    let m = TsveMaterial::isotropic(2, 0.3);
    let c = m.cbr(0, 1, [2.0, 1.0, 0.5]).unwrap();
    close(c.min, [0.95, -0.05, -0.55]);
    close(c.max, [3.05, 2.05, 1.55]);
    assert!(m.supports_time_saving());
}

/// Anisotropic TSVE: alpha = (0.1, 0.2, 0.3) on both ends, face link d = (1, 0, 0):
/// x in [0.9, 1.1], y in [-0.2, 0.2], z in [-0.3, 0.3].
#[test]
fn tsve_anisotropic_by_hand() {
    let m = TsveMaterial::anisotropic(2, [0.1, 0.2, 0.3]);
    let c = m.cbr(0, 1, [1.0, 0.0, 0.0]).unwrap();
    close(c.min, [0.9, -0.2, -0.3]);
    close(c.max, [1.1, 0.2, 0.3]);
    assert!(m.supports_time_saving());
    assert!(!TsveMaterial::heterogeneous(&[0.1, 0.2]).supports_time_saving());
}

#[test]
fn clamp_and_violation() {
    let m = TsveMaterial::isotropic(2, 0.1);
    let c = m.cbr(0, 1, [1.0, 0.0, 0.0]).unwrap();
    // Box: x in [0.9, 1.1], y, z in [-0.1, 0.1].
    assert!((c.violation([0.5, 0.0, 0.3]) - 0.4).abs() < 1e-12);
    close(c.clamp([0.5, 0.0, 0.3]), [0.9, 0.0, 0.1]);
    assert_eq!(c.violation([1.0, 0.05, -0.05]), 0.0);
}

#[test]
fn invalid_parameters_are_errors() {
    let bad = [
        GeneralizedMaterial::isotropic(-0.1, 1.2, 0.1),
        GeneralizedMaterial::isotropic(0.8, 1.2, -0.1),
        GeneralizedMaterial::isotropic(1.3, 1.2, 0.1),
        GeneralizedMaterial::isotropic(0.8, 0.9, 0.1),
        GeneralizedMaterial::isotropic(f64::NAN, 1.2, 0.1),
        GeneralizedMaterial::isotropic(0.8, f64::INFINITY, 0.1),
    ];
    for m in bad {
        assert!(matches!(m.validate(1), Err(ChainmailError::InvalidParameter { .. })), "{m:?}");
    }
    assert!(GeneralizedMaterial::default().validate(1).is_ok());
    assert!(matches!(
        TsveMaterial::isotropic(3, -0.1).validate(3),
        Err(ChainmailError::InvalidParameter { .. })
    ));
    assert!(matches!(
        TsveMaterial::isotropic(3, f64::NAN).validate(3),
        Err(ChainmailError::InvalidParameter { .. })
    ));
    assert!(matches!(
        TsveMaterial::isotropic(3, 0.1).validate(4),
        Err(ChainmailError::LengthMismatch { expected: 4, found: 3 })
    ));
    assert!(matches!(
        TsveMaterial::isotropic(3, 0.1).cbr(0, 7, [1.0, 0.0, 0.0]),
        Err(ChainmailError::IndexOutOfRange { index: 7, len: 3 })
    ));
}
