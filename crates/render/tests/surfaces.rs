//! Tests of `render_surfaces`: output size, coverage, colors, visibility,
//! degenerate input and errors.

use crate::common::{bumpy_sphere, decode, icosahedron, split_cube};
use fibfluid_render::{Colormap, RenderError, Surface, ViewOptions, render_surfaces, robust_range};

fn surface<'a>(p: &'a [[f64; 3]], t: &'a [[u32; 3]], s: &'a [f64], title: &str) -> Surface<'a> {
    Surface { positions: p, triangles: t, scalar: s, title: title.to_string() }
}

fn opts(width: u32, height: u32) -> ViewOptions {
    ViewOptions { width, height, scalar_label: "stress".into(), ..ViewOptions::default() }
}

/// Pixels of the vertical strip `x0..x1` of a decoded image.
fn column(img: &(u32, u32, Vec<[u8; 3]>), x0: u32, x1: u32) -> Vec<[u8; 3]> {
    let (w, h, px) = img;
    (0..*h).flat_map(|y| (x0..x1).map(move |x| px[(y * w + x) as usize])).collect()
}

fn is_gray(c: [u8; 3]) -> bool {
    let max = c.iter().max().copied().unwrap_or(0);
    let min = c.iter().min().copied().unwrap_or(0);
    max - min < 10
}

fn cosine(a: [f64; 3], b: [u8; 3]) -> f64 {
    let b = b.map(f64::from);
    let d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    d / ((a.iter().map(|x| x * x).sum::<f64>() * b.iter().map(|x| x * x).sum::<f64>()).sqrt())
}

/// Mean color of the colored (not gray, not background) pixels.
fn mean_color(pixels: &[[u8; 3]]) -> (usize, [f64; 3]) {
    let colored: Vec<_> = pixels.iter().filter(|c| !is_gray(**c)).collect();
    let mut sum = [0.0; 3];
    for c in &colored {
        for k in 0..3 {
            sum[k] += f64::from(c[k]);
        }
    }
    let n = colored.len().max(1) as f64;
    (colored.len(), sum.map(|s| s / n))
}

#[test]
fn png_decodes_to_panels_plus_color_bar() {
    let (p, t) = icosahedron();
    let s: Vec<f64> = p.iter().map(|q| q[1]).collect();
    let panels = [surface(&p, &t, &s, "left"), surface(&p, &t, &s, "right")];
    let png = render_surfaces(&panels, None, &opts(300, 200)).unwrap();
    let (w, h, px) = decode(&png);
    assert_eq!(h, 200);
    assert!(w > 600, "room for a color bar, got width {w}");
    assert!(w < 600 + 300, "color bar narrower than a panel, got width {w}");
    assert_eq!(px.len(), (w * h) as usize);
}

#[test]
fn icosahedron_covers_a_plausible_fraction_of_its_panel() {
    let (p, t) = icosahedron();
    let s: Vec<f64> = p.iter().map(|q| q[0] + q[2]).collect();
    let o = opts(400, 400);
    let img = decode(&render_surfaces(&[surface(&p, &t, &s, "ico")], None, &o).unwrap());
    let panel = column(&img, 0, 400);
    let covered = panel.iter().filter(|c| **c != o.background).count();
    let fraction = covered as f64 / panel.len() as f64;
    assert!(fraction > 0.10 && fraction < 0.90, "covered fraction {fraction}");
    // The color bar strip has pixels too.
    let strip = column(&img, 400, img.0);
    assert!(strip.iter().filter(|c| !is_gray(**c)).count() > 100);
}

#[test]
fn all_min_and_all_max_panels_get_the_color_map_endpoints() {
    let (p, t) = icosahedron();
    let zeros = vec![0.0; p.len()];
    let ones = vec![1.0; p.len()];
    for (cmap, gradient) in [(Colormap::Viridis, colorous::VIRIDIS), (Colormap::Turbo, colorous::TURBO)] {
        let o = ViewOptions { colormap: cmap, ..opts(240, 240) };
        let panels = [surface(&p, &t, &zeros, "min"), surface(&p, &t, &ones, "max")];
        let img = decode(&render_surfaces(&panels, None, &o).unwrap());
        let lo = gradient.eval_continuous(0.0).into_array();
        let hi = gradient.eval_continuous(1.0).into_array();
        let (n_min, mean_min) = mean_color(&column(&img, 0, 240));
        let (n_max, mean_max) = mean_color(&column(&img, 240, 480));
        assert!(n_min > 1000 && n_max > 1000, "{n_min} {n_max}");
        assert!(
            cosine(mean_min, lo) > cosine(mean_min, hi) + 0.05,
            "{cmap:?}: min panel mean {mean_min:?} vs {lo:?} / {hi:?}"
        );
        assert!(
            cosine(mean_max, hi) > cosine(mean_max, lo) + 0.05,
            "{cmap:?}: max panel mean {mean_max:?} vs {lo:?} / {hi:?}"
        );
    }
}

/// Counts panel pixels whose color points towards the top of viridis
/// (yellow) rather than its bottom (purple).
fn yellowish_pixels(face: usize) -> usize {
    let (p, t) = split_cube();
    let mut s = vec![0.0; p.len()];
    for v in 4 * face..4 * face + 4 {
        s[v] = 1.0;
    }
    let o = opts(300, 300);
    let img = decode(&render_surfaces(&[surface(&p, &t, &s, "cube")], Some((0.0, 1.0)), &o).unwrap());
    let lo = colorous::VIRIDIS.eval_continuous(0.0).into_array();
    let hi = colorous::VIRIDIS.eval_continuous(1.0).into_array();
    column(&img, 0, 300)
        .into_iter()
        .filter(|&c| !is_gray(c))
        .filter(|&c| {
            let c = c.map(f64::from);
            cosine(c, hi) > cosine(c, lo)
        })
        .count()
}

#[test]
fn far_faces_are_hidden_and_near_faces_shown() {
    // The default camera looks along (-1, -0.6, -1.6): the +x, +y, +z faces
    // (1, 3, 5) face it, the -x, -y, -z faces (0, 2, 4) are behind.
    for far in [0, 2, 4] {
        assert_eq!(yellowish_pixels(far), 0, "far face {far} shows through");
    }
    for near in [1, 3, 5] {
        assert!(yellowish_pixels(near) > 500, "near face {near} not seen");
    }
}

#[test]
fn constant_scalar_renders_in_a_single_color() {
    let (p, t) = icosahedron();
    let s = vec![2.5; p.len()];
    let o = opts(300, 300);
    let img = decode(&render_surfaces(&[surface(&p, &t, &s, "const")], None, &o).unwrap());
    let panel = column(&img, 0, 300);
    let colored: Vec<_> = panel.into_iter().filter(|c| !is_gray(*c)).collect();
    assert!(colored.len() > 9000, "{}", colored.len());
    // Every face has the same hue: the colors differ by shading only.
    let first = colored[0].map(f64::from);
    for c in &colored {
        assert!(cosine(first, *c) > 0.995, "{first:?} vs {c:?}");
    }
}

#[test]
fn degenerate_meshes_render_without_dividing_by_zero() {
    let o = opts(120, 120);
    // A flat square seen exactly edge-on: it projects onto a line.
    let flat = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.0, 0.0, 1.0]];
    let tris = [[0, 1, 2], [0, 2, 3]];
    let s = [0.0, 1.0, 2.0, 3.0];
    let edge_on = ViewOptions { view_dir: [0.0, 0.0, -1.0], ..o.clone() };
    let png = render_surfaces(&[surface(&flat, &tris, &s, "edge-on")], None, &edge_on).unwrap();
    assert_eq!(decode(&png).1, 120);
    // Everything collapsed onto one point, plus zero-area triangles.
    let point = [[1.0, 2.0, 3.0]; 3];
    let png = render_surfaces(&[surface(&point, &[[0, 1, 2]], &[1.0; 3], "point")], None, &o).unwrap();
    assert_eq!(decode(&png).1, 120);
    // Collinear vertices.
    let line = [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]];
    let png = render_surfaces(&[surface(&line, &[[0, 1, 2]], &[0.0; 3], "")], None, &o).unwrap();
    assert_eq!(decode(&png).1, 120);
    // Up parallel to the view direction.
    let top_down = ViewOptions { view_dir: [0.0, -1.0, 0.0], up: [0.0, 1.0, 0.0], ..o.clone() };
    let (p, t) = icosahedron();
    let s = vec![0.0; p.len()];
    let img = decode(&render_surfaces(&[surface(&p, &t, &s, "top")], None, &top_down).unwrap());
    assert!(column(&img, 0, 120).iter().filter(|c| !is_gray(**c)).count() > 1000);
}

#[test]
fn six_thousand_triangles_at_800x800_render() {
    let (p, t) = bumpy_sphere(60, 51);
    assert_eq!(t.len(), 6000);
    let s: Vec<f64> = p.iter().map(|q| q[0] * q[1]).collect();
    let o = opts(800, 800);
    // Only the result is checked: timings belong in benches, not in tests.
    let png = render_surfaces(&[surface(&p, &t, &s, "sphere")], None, &o).unwrap();
    assert_eq!(decode(&png).1, 800);
}

#[test]
fn bad_input_gives_the_matching_error() {
    let (p, t) = icosahedron();
    let s = vec![0.0; p.len()];
    let o = opts(100, 100);
    let ok = surface(&p, &t, &s, "ok");

    assert!(matches!(render_surfaces(&[], None, &o), Err(RenderError::EmptyInput { .. })));
    assert!(matches!(
        render_surfaces(&[surface(&p, &[], &s, "no tris")], None, &o),
        Err(RenderError::EmptyInput { .. })
    ));
    assert!(matches!(
        render_surfaces(&[surface(&[], &[], &[], "nothing")], None, &o),
        Err(RenderError::EmptyInput { .. })
    ));

    let mut bad_t = t.clone();
    bad_t[7] = [0, 1, 12];
    let err = render_surfaces(&[ok.clone(), surface(&p, &bad_t, &s, "bad")], None, &o);
    assert_eq!(err, Err(RenderError::IndexOutOfRange { panel: 1, triangle: 7, index: 12, vertex_count: 12 }));
    let msg = err.unwrap_err().to_string();
    assert!(msg.contains("triangle 7") && msg.contains("panel 1"), "{msg}");

    let mut bad_p = p.clone();
    bad_p[5][2] = f64::NAN;
    let err = render_surfaces(&[surface(&bad_p, &t, &s, "nan")], None, &o).unwrap_err();
    assert!(matches!(err, RenderError::NonFinitePosition { panel: 0, vertex: 5, .. }), "{err:?}");
    assert!(err.to_string().contains("vertex 5"), "{err}");
    bad_p[5][2] = f64::INFINITY;
    assert!(matches!(
        render_surfaces(&[surface(&bad_p, &t, &s, "inf")], None, &o),
        Err(RenderError::NonFinitePosition { vertex: 5, .. })
    ));

    let mut bad_s = s.clone();
    bad_s[3] = f64::NEG_INFINITY;
    let err = render_surfaces(&[surface(&p, &t, &bad_s, "s")], None, &o).unwrap_err();
    assert!(matches!(err, RenderError::NonFiniteScalar { panel: 0, vertex: 3, .. }), "{err:?}");
    assert!(err.to_string().contains("vertex 3"), "{err}");

    assert!(matches!(
        render_surfaces(&[surface(&p, &t, &s[..5], "short")], None, &o),
        Err(RenderError::ScalarLength { scalars: 5, vertices: 12, .. })
    ));

    for (w, h) in [(0, 100), (100, 0)] {
        assert_eq!(
            render_surfaces(std::slice::from_ref(&ok), None, &opts(w, h)),
            Err(RenderError::ZeroSize { width: w, height: h })
        );
    }
    assert!(matches!(
        render_surfaces(std::slice::from_ref(&ok), None, &opts(100_000, 100_000)),
        Err(RenderError::ImageTooLarge { .. })
    ));

    for range in [(1.0, 0.0), (f64::NAN, 1.0), (0.0, f64::INFINITY)] {
        assert!(matches!(
            render_surfaces(std::slice::from_ref(&ok), Some(range), &o),
            Err(RenderError::InvalidRange { .. })
        ));
    }

    for (view_dir, up, what) in [
        ([0.0; 3], [0.0, 1.0, 0.0], "view_dir"),
        ([f64::NAN, 0.0, 1.0], [0.0, 1.0, 0.0], "view_dir"),
        ([0.0, 0.0, -1.0], [0.0; 3], "up"),
    ] {
        let o = ViewOptions { view_dir, up, ..opts(100, 100) };
        let err = render_surfaces(std::slice::from_ref(&ok), None, &o).unwrap_err();
        assert!(matches!(err, RenderError::InvalidView { what: w, .. } if w == what), "{err:?}");
    }
}

#[test]
fn tiny_images_and_extreme_coordinates_do_not_panic() {
    let (p, t) = icosahedron();
    let s: Vec<f64> = p.iter().map(|q| q[2]).collect();
    for (w, h) in [(1, 1), (3, 50), (50, 3), (16, 16)] {
        let png = render_surfaces(&[surface(&p, &t, &s, "tiny title")], None, &opts(w, h)).unwrap();
        assert_eq!(decode(&png).1, h);
    }
    // Huge and tiny magnitudes in positions and scalars.
    for k in [1e-300, 1e-10, 1e10, 1e150, 1e300] {
        let big: Vec<[f64; 3]> = p.iter().map(|q| q.map(|c| c * k)).collect();
        let sk: Vec<f64> = s.iter().map(|v| v * k).collect();
        let png = render_surfaces(&[surface(&big, &t, &sk, "scaled")], None, &opts(64, 64)).unwrap();
        assert_eq!(decode(&png).1, 64);
    }
    // A scalar range whose width overflows f64.
    let s_wide: Vec<f64> = (0..p.len()).map(|i| if i % 2 == 0 { -1.5e308 } else { 1.5e308 }).collect();
    let png = render_surfaces(&[surface(&p, &t, &s_wide, "wide")], None, &opts(64, 64)).unwrap();
    assert_eq!(decode(&png).1, 64);
    // Values far outside an explicit range are clamped to its ends.
    let s_out: Vec<f64> = s.iter().map(|v| v * 1e6).collect();
    let png = render_surfaces(&[surface(&p, &t, &s_out, "")], Some((0.0, 1.0)), &opts(64, 64));
    assert!(png.is_ok());
}

/// A few extreme values do not set the color scale: 1,000 pressures spread over 1 to 1,000
/// with five at 1e6 get the range (0, the 95th percentile of the nonzero values), which the
/// spread puts at 954 (the 954th of 1,005 values); without the outliers, or with a largest
/// value under three times the quantile, the full range stands (`None`). Zeros (out of
/// contact) are not counted.
#[test]
fn a_few_outliers_do_not_set_the_color_scale() {
    let mut values: Vec<f64> = (1..=1000).map(f64::from).collect();
    values.extend([0.0; 300]);
    assert_eq!(robust_range(&values), None);
    values.extend([1e6; 5]);
    let (lo, hi) = robust_range(&values).expect("five values at 1e6 are outliers");
    assert!(lo == 0.0 && hi == 954.0, "({lo}, {hi})");
    values.truncate(1300);
    values.push(2500.0);
    assert_eq!(robust_range(&values), None, "2.5 times the quantile is not an outlier");
    assert_eq!(robust_range(&[0.0, 0.0]), None);
}

/// With `no_value`, NaN scalars are vertices without a value: a panel of them is painted in
/// that color, shaded (red and blue equal, no green), not refused.
#[test]
fn vertices_without_a_value_are_painted_in_the_no_value_color() {
    let (p, t) = icosahedron();
    let none = vec![f64::NAN; p.len()];
    let o = ViewOptions { no_value: Some([200, 0, 200]), ..opts(240, 240) };
    let img = decode(&render_surfaces(&[surface(&p, &t, &none, "none")], Some((0.0, 1.0)), &o).unwrap());
    // Not gray: not the background, nor the title's text.
    let painted: Vec<[u8; 3]> = column(&img, 0, 240).into_iter().filter(|c| !is_gray(*c)).collect();
    assert!(painted.len() > 1000, "{} pixels", painted.len());
    assert!(painted.iter().all(|c| c[1] == 0 && c[0] == c[2] && c[0] > 50), "{:?}", painted[0]);
    // Without `no_value` the same scalars are an error.
    assert!(matches!(
        render_surfaces(&[surface(&p, &t, &none, "none")], None, &opts(240, 240)),
        Err(RenderError::NonFiniteScalar { vertex: 0, .. })
    ));
}

/// `side_by_side` puts the second picture right of the first, tops aligned, on white.
#[test]
fn side_by_side_joins_pictures_left_to_right() {
    let (p, t) = icosahedron();
    let s: Vec<f64> = p.iter().map(|q| q[1]).collect();
    let a = render_surfaces(&[surface(&p, &t, &s, "a")], None, &opts(200, 150)).unwrap();
    let b = render_surfaces(&[surface(&p, &t, &s, "b")], None, &opts(180, 260)).unwrap();
    let (da, db) = (decode(&a), decode(&b));
    let (w, h, px) = decode(&fibfluid_render::side_by_side(&[&a, &b]).unwrap());
    assert_eq!((w, h), (da.0 + db.0, 260));
    for y in 0..h {
        for x in 0..w {
            let expected = if x >= da.0 {
                db.2[(y * db.0 + x - da.0) as usize]
            } else if y < da.1 {
                da.2[(y * da.0 + x) as usize]
            } else {
                [255; 3]
            };
            assert_eq!(px[(y * w + x) as usize], expected, "pixel {x}, {y}");
        }
    }
    assert!(fibfluid_render::side_by_side(&[b"not a png"]).is_err());
}
