//! Label images: the NIfTI reader and writer, and surfaces extracted from labels.

use std::f64::consts::PI;
use std::io::Write;

use fibfluid_geometry::{
    ImageProblem, LabelImage, LabelSelection, LabelType, LengthUnit, NiftiWriteOptions,
    SMOOTH_VOLUME_TOLERANCE, SurfaceError, SurfaceOptions, extract_surface, nifti_bytes, read_nifti,
    read_nifti_bytes, write_nifti,
};

const LIMIT: u64 = 2 << 30;

/// Labels of balls around the centre of an `n^3` grid: `(radius in voxels, label)`, later
/// entries painted over earlier ones; a voxel is inside when its centre is within the radius.
fn balls(n: usize, spacing: f64, radii: &[(f64, u32)]) -> LabelImage {
    let c = (n as f64 - 1.0) / 2.0;
    let mut labels = vec![0u32; n * n * n];
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let r2 = [i, j, k].iter().map(|&x| (x as f64 - c).powi(2)).sum::<f64>();
                for &(r, l) in radii {
                    if r2 <= r * r {
                        labels[i + n * (j + n * k)] = l;
                    }
                }
            }
        }
    }
    LabelImage::new([n, n, n], [spacing; 3], labels).unwrap()
}

fn opts(selection: LabelSelection) -> SurfaceOptions {
    SurfaceOptions { selection, ..SurfaceOptions::default() }
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

#[test]
fn ball_surface_is_closed_outward_and_has_the_voxel_volume() {
    let image = balls(25, 1e-3, &[(10.0, 1)]);
    let s = extract_surface(&image, &opts(LabelSelection::NonZero)).unwrap();
    assert!(!s.validation.flipped, "extracted surface came out inward");
    assert_eq!(s.validation.genus, 0);
    assert!(s.volume > 0.0);
    let sphere = 4.0 / 3.0 * PI * 1e-6;
    let (to_voxels, to_sphere) = (rel(s.volume, s.voxel_volume), rel(s.volume, sphere));
    eprintln!(
        "ball r=10: {} voxels, {} vertices, volume {:.6e} m^3: {:.2} % from voxels, {:.2} % from 4/3 pi r^3",
        s.voxels,
        s.mesh.n_vertices(),
        s.volume,
        100.0 * to_voxels,
        100.0 * to_sphere
    );
    assert!(to_voxels < 0.03, "{to_voxels}");
    assert!(to_sphere < 0.05, "{to_sphere}");
    // Smoothing keeps a valid surface and the voxels' volume (its level is sought for it).
    let smooth =
        extract_surface(&image, &SurfaceOptions { smooth: true, ..opts(LabelSelection::Label(1)) }).unwrap();
    eprintln!("smoothed: {:.3} % from voxels", 100.0 * rel(smooth.volume, s.voxel_volume));
    assert!(rel(smooth.volume, s.voxel_volume) <= SMOOTH_VOLUME_TOLERANCE);
}

#[test]
fn millimetres_and_metres_give_the_same_surface() {
    let image = balls(17, 1e-3, &[(6.0, 1)]);
    // NIfTI-1 stores lengths as f32, which cannot hold 0.001 exactly: NIfTI-2 (f64) does.
    let read = |unit| {
        let o = NiftiWriteOptions { unit, nifti2: true, ..NiftiWriteOptions::default() };
        read_nifti_bytes(&nifti_bytes(&image, &o), LIMIT).unwrap()
    };
    let (mm, m) = (read(LengthUnit::Millimetre), read(LengthUnit::Metre));
    assert_eq!(mm.spacing, [1e-3; 3]);
    // NIfTI has no centimetre: asked for one, the writer stores millimetres.
    assert_eq!(read(LengthUnit::Centimetre), mm);
    assert!(read(LengthUnit::Micrometre).spacing.iter().all(|&h| rel(h, 1e-3) < 1e-12));
    let (a, b) = [mm, m].map(|i| extract_surface(&i, &opts(LabelSelection::Label(1))).unwrap()).into();
    assert_eq!(a.mesh.triangles(), b.mesh.triangles());
    for (p, q) in a.mesh.positions().iter().zip(b.mesh.positions()) {
        for c in 0..3 {
            assert!((p[c] - q[c]).abs() <= 1e-12 * 6e-3, "{p:?} {q:?}");
        }
    }
    // NIfTI-1 (f32 pixdim): the metre file is off by f32(0.001)'s rounding, 4.7e-8.
    let o = NiftiWriteOptions { unit: LengthUnit::Metre, ..NiftiWriteOptions::default() };
    let m1 = read_nifti_bytes(&nifti_bytes(&image, &o), LIMIT).unwrap();
    assert!(rel(m1.spacing[0], 1e-3) < 1e-7);
}

#[test]
fn two_labels_give_two_valid_surfaces() {
    let image = balls(25, 1e-3, &[(10.0, 1), (5.0, 2)]);
    let inner = extract_surface(&image, &opts(LabelSelection::Label(2))).unwrap();
    let body = extract_surface(&image, &opts(LabelSelection::NonZero)).unwrap();
    assert!(rel(inner.volume, inner.voxel_volume) < 0.05, "{}", rel(inner.volume, inner.voxel_volume));
    assert!(body.volume > 5.0 * inner.volume);
    // Label 1 alone is a shell: a body with one cavity, the hole of label 2 (its volume
    // within the voxels' 5 %); filled, it is the whole body.
    let shell = extract_surface(&image, &opts(LabelSelection::Label(1))).unwrap();
    assert_eq!(shell.validation.cavities.len(), 1);
    let hole = shell.validation.cavities[0];
    assert!(rel(hole, inner.volume) < 0.05, "{hole} vs {}", inner.volume);
    assert!(rel(shell.volume + hole, body.volume) < 0.05);
    let filled =
        extract_surface(&image, &SurfaceOptions { fill_cavities: true, ..opts(LabelSelection::Label(1)) })
            .unwrap();
    assert_eq!(filled.voxels, body.voxels);
    assert!(rel(filled.volume, body.volume) < 1e-12);
    assert!(matches!(
        extract_surface(&image, &opts(LabelSelection::Label(3))),
        Err(SurfaceError::Empty { .. })
    ));
}

#[test]
fn decimating_to_a_vertex_target_keeps_the_volume() {
    let image = balls(41, 1e-3, &[(18.0, 1)]);
    let full = extract_surface(&image, &opts(LabelSelection::NonZero)).unwrap();
    let target = full.mesh.n_vertices() / 5;
    let coarse = extract_surface(
        &image,
        &SurfaceOptions { target_vertices: Some(target), ..opts(LabelSelection::NonZero) },
    )
    .unwrap();
    let (to_full, to_voxels) = (rel(coarse.volume, full.volume), rel(coarse.volume, coarse.voxel_volume));
    eprintln!(
        "decimated: {} -> {} vertices (target {target}, block {}), volume {:.2e} from the full surface, \
         {:.2} % from voxels",
        full.mesh.n_vertices(),
        coarse.mesh.n_vertices(),
        coarse.block,
        to_full,
        100.0 * to_voxels
    );
    // Decimated, not resampled: the full-resolution surface's volume, within 1 %.
    assert!(coarse.mesh.n_vertices() <= target && coarse.block == 1);
    assert!(!coarse.validation.flipped && coarse.validation.genus == 0);
    assert!(to_full < 0.01, "{to_full}");
    assert!(to_voxels < 0.03, "{to_voxels}");
    assert!(matches!(
        extract_surface(
            &image,
            &SurfaceOptions { target_vertices: Some(3), ..opts(LabelSelection::NonZero) }
        ),
        Err(SurfaceError::TargetTooSmall { .. })
    ));
}

#[test]
fn nifti_round_trips_bit_for_bit() {
    let image = balls(9, 1e-3, &[(3.0, 1), (1.5, 300)]);
    for nifti2 in [false, true] {
        for label_type in
            [None, Some(LabelType::I16), Some(LabelType::I32), Some(LabelType::F32), Some(LabelType::F64)]
        {
            let o = NiftiWriteOptions { label_type, nifti2, ..NiftiWriteOptions::default() };
            let bytes = nifti_bytes(&image, &o);
            let back = read_nifti_bytes(&bytes, LIMIT).unwrap();
            assert_eq!(back, image);
            assert_eq!(nifti_bytes(&back, &o), bytes);
        }
    }
    let dir = std::env::temp_dir().join(format!("fibfluid-image-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for gzip in [false, true] {
        let path = dir.join(if gzip { "ball.nii.gz" } else { "ball.nii" });
        write_nifti(&path, &image, &NiftiWriteOptions { gzip, ..NiftiWriteOptions::default() }).unwrap();
        assert_eq!(read_nifti(&path).unwrap(), image);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The bytes of a small valid NIfTI-1 image (4 x 4 x 4, uint8, 1 mm) to damage.
fn valid() -> Vec<u8> {
    nifti_bytes(&balls(4, 1e-3, &[(1.5, 1)]), &NiftiWriteOptions::default())
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    gz.write_all(bytes).unwrap();
    gz.finish().unwrap()
}

/// Reads `bytes` and expects an error (the size checks name what the header claims, so a
/// refusal here was made from the header, before the voxels were allocated).
fn refused(bytes: &[u8]) -> ImageProblem {
    read_nifti_bytes(bytes, LIMIT).expect_err("a bad image was accepted")
}

#[test]
fn bad_headers_are_refused_quickly() {
    let patch = |off: usize, b: &[u8]| {
        let mut v = valid();
        v[off..off + b.len()].copy_from_slice(b);
        v
    };
    assert!(matches!(refused(&patch(344, b"ni1\0")), ImageProblem::BadMagic { .. }));
    assert!(matches!(refused(&patch(0, &[0; 4])), ImageProblem::NotNifti { .. }));
    let v = valid();
    assert!(matches!(refused(&v[..v.len() - 1]), ImageProblem::Truncated { .. }));
    assert!(matches!(refused(&v[..200]), ImageProblem::TooShort { .. }));
    assert!(matches!(refused(&gzip(&v[..v.len() - 10])), ImageProblem::Truncated { .. }));
    assert!(matches!(refused(&patch(80, &0f32.to_le_bytes())), ImageProblem::BadSpacing { axis: 1, .. }));
    assert!(matches!(refused(&patch(84, &(-1f32).to_le_bytes())), ImageProblem::BadSpacing { axis: 2, .. }));
    assert!(matches!(refused(&patch(88, &f32::NAN.to_le_bytes())), ImageProblem::BadSpacing { axis: 3, .. }));
    assert!(matches!(refused(&patch(40, &2i16.to_le_bytes())), ImageProblem::TooFewDimensions { ndim: 2 }));
    let mut four_d = patch(40, &4i16.to_le_bytes());
    four_d[48..50].copy_from_slice(&2i16.to_le_bytes());
    assert!(matches!(refused(&four_d), ImageProblem::BadDimension { axis: 4, size: 2 }));
    assert!(matches!(
        refused(&patch(42, &(-4i16).to_le_bytes())),
        ImageProblem::BadDimension { axis: 1, .. }
    ));
    assert!(matches!(
        refused(&patch(70, &32i16.to_le_bytes())),
        ImageProblem::UnsupportedDatatype { code: 32 }
    ));
    // 10^12 voxels claimed by a 416-byte file, and by a gzip of it.
    let mut huge = valid();
    for d in 0..3 {
        huge[42 + 2 * d..44 + 2 * d].copy_from_slice(&10000i16.to_le_bytes());
    }
    assert!(matches!(refused(&huge), ImageProblem::TooManyVoxels { voxels: 1_000_000_000_000, .. }));
    assert!(matches!(refused(&gzip(&huge)), ImageProblem::TooManyVoxels { .. }));
    // A gzip bomb: a 4^3 header followed by 256 MiB of zeros, 256 KiB compressed.
    let mut bomb = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    bomb.write_all(&valid()).unwrap();
    let zeros = vec![0u8; 1 << 20];
    for _ in 0..256 {
        bomb.write_all(&zeros).unwrap();
    }
    assert!(matches!(refused(&bomb.finish().unwrap()), ImageProblem::GzipTooLarge { expected: 416 }));
    // Values that are not labels.
    let image = balls(4, 1e-3, &[(1.5, 1)]);
    let mut float =
        nifti_bytes(&image, &NiftiWriteOptions { label_type: Some(LabelType::F32), ..Default::default() });
    float[352..356].copy_from_slice(&1.5f32.to_le_bytes());
    assert!(matches!(refused(&float), ImageProblem::NotALabel { voxel: 0, value: 1.5 }));
    let mut negative =
        nifti_bytes(&image, &NiftiWriteOptions { label_type: Some(LabelType::I16), ..Default::default() });
    negative[354..356].copy_from_slice(&(-3i16).to_le_bytes());
    assert!(matches!(refused(&negative), ImageProblem::NotALabel { voxel: 1, value: -3.0 }));
}

#[test]
fn errors_name_the_file() {
    let path = std::env::temp_dir().join(format!("fibfluid-bad-magic-{}.nii", std::process::id()));
    let mut v = valid();
    v[344] = b'x';
    std::fs::write(&path, v).unwrap();
    let e = read_nifti(&path).unwrap_err();
    std::fs::remove_file(&path).unwrap();
    let text = e.to_string();
    assert!(
        text.contains(&*path.to_string_lossy()) && text.contains("magic") && !text.contains('\n'),
        "{text}"
    );
}

#[test]
fn big_endian_files_are_read() {
    let image = balls(5, 1e-3, &[(2.0, 7)]);
    let mut v =
        nifti_bytes(&image, &NiftiWriteOptions { label_type: Some(LabelType::I16), ..Default::default() });
    // Swap every numeric field the writer sets, then the voxels.
    let mut swap = |off: usize, width: usize, count: usize| {
        for n in 0..count {
            v[off + n * width..off + (n + 1) * width].reverse();
        }
    };
    swap(0, 4, 1);
    swap(40, 2, 8);
    swap(70, 2, 2);
    swap(76, 4, 8);
    swap(108, 4, 3);
    swap(252, 2, 2);
    swap(256, 4, 18);
    swap(352, 2, 125);
    assert_eq!(read_nifti_bytes(&v, LIMIT).unwrap(), image);
}

#[test]
fn a_mirroring_sform_still_gives_an_outward_surface() {
    let mut image = balls(17, 1e-3, &[(6.0, 1)]);
    let plain = extract_surface(&image, &opts(LabelSelection::NonZero)).unwrap();
    // x mirrored, y and z swapped, shifted: a left-handed voxel-to-world map, as many scans have.
    image.affine = [[-1e-3, 0.0, 0.0, 0.05], [0.0, 0.0, 1e-3, -0.02], [0.0, 1e-3, 0.0, 0.01]];
    image.affine_source = fibfluid_geometry::AffineSource::Sform;
    let back = read_nifti_bytes(&nifti_bytes(&image, &NiftiWriteOptions::default()), LIMIT).unwrap();
    assert_eq!(back.affine_source, fibfluid_geometry::AffineSource::Sform);
    let s = extract_surface(&back, &opts(LabelSelection::NonZero)).unwrap();
    assert!(!s.validation.flipped);
    assert!(rel(s.volume, plain.volume) < 1e-6, "{} {}", s.volume, plain.volume);
}

#[test]
fn the_phantom_fixture_gives_a_body_and_a_lesion() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/images/phantom.nii.gz");
    let image = read_nifti(path).unwrap();
    assert_eq!((image.dims, image.spacing), ([24, 24, 20], [2e-3; 3]));
    assert_eq!(image.labels_present(), vec![1, 2]);
    let body = extract_surface(
        &image,
        &SurfaceOptions { target_vertices: Some(600), ..opts(LabelSelection::NonZero) },
    )
    .unwrap();
    let lesion = extract_surface(&image, &opts(LabelSelection::Label(2))).unwrap();
    let ellipsoid = 4.0 / 3.0 * PI * 20e-3 * 16e-3 * 14e-3;
    let full = extract_surface(&image, &opts(LabelSelection::NonZero)).unwrap();
    eprintln!(
        "phantom: body {} vertices (block {}), {:.2e} from the full surface ({} vertices), {:.2} % from \
         voxels, {:.2} % from the ellipsoid",
        body.mesh.n_vertices(),
        body.block,
        rel(body.volume, full.volume),
        full.mesh.n_vertices(),
        100.0 * rel(body.volume, body.voxel_volume),
        100.0 * rel(body.volume, ellipsoid)
    );
    // Decimation keeps the full-resolution surface's volume (resampling on 3-voxel blocks
    // used to lose about a tenth of it).
    assert!(body.mesh.n_vertices() <= 600 && body.block == 1);
    assert!(rel(body.volume, full.volume) < 0.01);
    assert!(rel(body.volume, ellipsoid) < 0.03);
    assert!(rel(full.volume, full.voxel_volume) < 0.03);
    assert!(lesion.volume > 0.0 && lesion.volume < 0.1 * body.volume);
}

/// A surface above 200 000 vertices and 20 times the target is resampled before it is
/// decimated: `block` says so, and the result is still one valid surface near the volume.
#[test]
fn an_enormous_surface_is_resampled_before_decimation() {
    let image = balls(130, 1e-3, &[(62.0, 1)]);
    let s = extract_surface(
        &image,
        &SurfaceOptions { target_vertices: Some(5000), ..opts(LabelSelection::NonZero) },
    )
    .unwrap();
    let error = rel(s.volume, s.voxel_volume);
    eprintln!(
        "ball r=62: {} vertices (block {}), {:.2} % from voxels",
        s.mesh.n_vertices(),
        s.block,
        100.0 * error
    );
    assert!(s.block >= 3 && s.mesh.n_vertices() <= 5000, "block {}", s.block);
    assert!(!s.validation.flipped && s.validation.genus == 0);
    assert!(error < 0.03, "{error}");
}
