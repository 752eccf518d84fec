//! Tests of `loglog_chart` and `pareto_front`.

use crate::common::decode;
use fibfluid_render::{RenderError, Series, loglog_chart, pareto_front};

fn series() -> Vec<Series> {
    vec![
        Series { label: "dense LU".into(), points: vec![(1e-3, 2.0), (1e-2, 0.5), (1e-1, 0.1), (1.0, 0.02)] },
        Series { label: "structured".into(), points: vec![(3e-3, 1.0), (2e-2, 0.08), (0.3, 0.01)] },
    ]
}

#[test]
fn chart_decodes_to_the_requested_size_with_series_colors() {
    let pareto = [(1e-3, 2.0), (3e-3, 1.0), (2e-2, 0.08), (0.3, 0.01)];
    let png = loglog_chart("cost vs error", "time [s]", "error", &series(), &pareto, 640, 480).unwrap();
    let (w, h, px) = decode(&png);
    assert_eq!((w, h), (640, 480));
    // Each series is drawn in its Tableau 10 color.
    for c in &colorous::TABLEAU10[..2] {
        let c = c.into_array();
        let n = px.iter().filter(|p| **p == c).count();
        assert!(n > 50, "color {c:?} appears {n} times");
    }
    // Black rings / dashed line / text.
    assert!(px.iter().filter(|p| **p == [0, 0, 0]).count() > 100);
}

#[test]
fn chart_without_pareto_points_and_with_one_point_series() {
    let one = [Series { label: "single".into(), points: vec![(5.0, 5.0)] }];
    let (w, h, _) = decode(&loglog_chart("t", "x", "y", &one, &[], 300, 200).unwrap());
    assert_eq!((w, h), (300, 200));
    // Pareto points alone are enough.
    let (w, h, _) = decode(&loglog_chart("t", "x", "y", &[], &[(1.0, 1.0)], 200, 300).unwrap());
    assert_eq!((w, h), (200, 300));
}

#[test]
fn chart_errors_name_the_series_and_point() {
    assert_eq!(
        loglog_chart("t", "x", "y", &series(), &[], 0, 100),
        Err(RenderError::ZeroSize { width: 0, height: 100 })
    );
    assert!(matches!(
        loglog_chart("t", "x", "y", &series(), &[], 100_000, 100_000),
        Err(RenderError::ImageTooLarge { .. })
    ));
    assert!(matches!(loglog_chart("t", "x", "y", &[], &[], 100, 100), Err(RenderError::EmptyInput { .. })));
    let empty = [Series { label: "empty".into(), points: vec![] }];
    assert!(matches!(
        loglog_chart("t", "x", "y", &empty, &[], 100, 100),
        Err(RenderError::EmptyInput { .. })
    ));

    for bad in [(0.0, 1.0), (1.0, -2.0), (f64::NAN, 1.0), (1.0, f64::INFINITY)] {
        let mut s = series();
        s[1].points[2] = bad;
        let err = loglog_chart("t", "x", "y", &s, &[], 100, 100).unwrap_err();
        assert!(
            matches!(&err, RenderError::NonPositiveLog { series, point: 2, .. } if series == "structured"),
            "{err:?}"
        );
        let msg = err.to_string();
        assert!(msg.contains("structured") && msg.contains("point 2"), "{msg}");
    }
    let err = loglog_chart("t", "x", "y", &series(), &[(1.0, 1.0), (0.0, 1.0)], 100, 100).unwrap_err();
    assert!(
        matches!(&err, RenderError::NonPositiveLog { series, point: 1, .. } if series == "Pareto front"),
        "{err:?}"
    );
}

#[test]
fn pareto_front_of_a_hand_made_set() {
    let points = [
        (1.0, 5.0),      // 0: front
        (2.0, 3.0),      // 1: front
        (3.0, 4.0),      // 2: dominated by 1
        (4.0, 1.0),      // 3: front
        (2.0, 6.0),      // 4: dominated by 1 (same x, larger y)
        (5.0, 1.0),      // 5: dominated by 3 (same y, larger x)
        (0.5, 10.0),     // 6: front (smallest x)
        (f64::NAN, 0.0), // 7: never on the front
        (6.0, 0.5),      // 8: front (smallest y)
        (2.0, 3.0),      // 9: duplicate of 1: kept
    ];
    assert_eq!(pareto_front(&points), vec![6, 0, 1, 9, 3, 8]);
    assert_eq!(pareto_front(&[]), Vec::<usize>::new());
    assert_eq!(pareto_front(&[(3.0, 3.0)]), vec![0]);
    // A chain where every point is dominated by the first.
    assert_eq!(pareto_front(&[(1.0, 1.0), (2.0, 2.0), (3.0, 3.0)]), vec![0]);
}

#[test]
fn tiny_charts_and_extreme_magnitudes_do_not_panic() {
    for (w, h) in [(1, 1), (5, 5), (40, 30), (30, 400)] {
        let (dw, dh, _) = decode(&loglog_chart("t", "x", "y", &series(), &[(1e-3, 2.0)], w, h).unwrap());
        assert_eq!((dw, dh), (w, h));
    }
    let wide = [Series { label: "wide".into(), points: vec![(1e-100, 1e100), (1e100, 1e-100), (1.0, 1.0)] }];
    let (dw, dh, _) = decode(&loglog_chart("wide", "x", "y", &wide, &[], 400, 300).unwrap());
    assert_eq!((dw, dh), (400, 300));
    let too_wide = [Series { label: "too wide".into(), points: vec![(1.0, 1.0), (1e200, 1.0)] }];
    assert!(matches!(
        loglog_chart("t", "x", "y", &too_wide, &[], 400, 300),
        Err(RenderError::NonPositiveLog { point: 1, .. })
    ));
}
