use super::*;
use crate::envmap::EnvMap;
use crate::ward::Ward;
use crate::{Lighting, Quality, View, render, render_normals};
use reflectance_core::decode::Limits;

fn close(a: [f32; 3], b: Vec3, tolerance: f64) -> bool {
    let d = Vec3::new(f64::from(a[0]), f64::from(a[1]), f64::from(a[2])) - b;
    d.dot(d).sqrt() <= tolerance
}

#[test]
fn the_sphere_shape_is_the_sphere_renderers_geometry() {
    let size = 40;
    let normals = rasterize(&Shape::Sphere, &Pose::random(&mut Rng::new(3)), size, 1).unwrap();
    let grid = Grid::new(size);
    for row in 0..size {
        for col in 0..size {
            let (x, y) = grid.pixel(row, col).centre;
            let expected = crate::sphere_normal(x, y);
            let found = normals.at(row, col);
            assert_eq!(found.is_some(), expected.is_some(), "({row}, {col})");
            if let (Some(f), Some(e)) = (found, expected) {
                assert_eq!(f, [e.x as f32, e.y as f32, e.z as f32]);
            }
            let coverage = if expected.is_some() { 1.0 } else { 0.0 };
            assert_eq!(normals.coverage(row, col), coverage);
        }
    }
}

#[test]
fn the_sphere_shape_fills_the_renderers_circle() {
    let size = 44;
    let normals = rasterize(&Shape::Sphere, &Pose::identity(), size, 4).unwrap();
    let area: f64 = (0..size * size)
        .map(|i| f64::from(normals.coverage(i / size, i % size)))
        .sum();
    let r = crate::circle(size).r;
    let disc = std::f64::consts::PI * r * r;
    assert!((area - disc).abs() < 0.01 * disc, "{area} vs {disc}");
}

fn shipped_lighting() -> Lighting {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../data/probes/polyhaven_dresden_square.hdr");
    Lighting::new(EnvMap::load(&path).unwrap())
}

fn material(rho_d: f64, rho_s: f64, alpha: f64) -> Ward {
    Ward {
        rho_d,
        rho_s,
        alpha,
    }
}

/// Mean |a − b| over pixels, relative to the mean of a.
fn relative_difference(a: &[f32], b: &[f32]) -> f64 {
    let diff: f64 = a.iter().zip(b).map(|(x, y)| f64::from((x - y).abs())).sum();
    let total: f64 = a.iter().map(|&x| f64::from(x)).sum();
    diff / total
}

/// The shape renderer differs from the sphere renderer no more than the sphere renderer
/// differs from itself with another seed: within sampling noise.
#[test]
fn rendering_the_sphere_shapes_normals_is_rendering_the_sphere() {
    let lighting = shipped_lighting();
    let size = 48;
    let quality = Quality::default();
    let normals = rasterize(
        &Shape::Sphere,
        &Pose::identity(),
        size,
        quality.pixel_samples,
    )
    .unwrap();
    let view = View::default();
    for m in [
        material(0.8, 0.0, 0.0),
        material(0.3, 0.1, 0.05),
        material(0.0, 0.75, 0.0),
    ] {
        let sphere = render(&lighting, &m, size, &view, &quality, &mut Rng::new(5));
        let other = render(&lighting, &m, size, &view, &quality, &mut Rng::new(6));
        let shape = render_normals(&lighting, &m, &view, &normals, &quality, &mut Rng::new(5));
        let noise = relative_difference(&sphere.luminance, &other.luminance);
        let luminance = relative_difference(&sphere.luminance, &shape.luminance);
        let coverage = relative_difference(&sphere.coverage, &shape.coverage);
        let noise_coverage = relative_difference(&sphere.coverage, &other.coverage);
        assert!(
            luminance < 1.5 * noise + 1e-3,
            "{m:?}: {luminance} (noise {noise})"
        );
        assert!(
            coverage < 1.5 * noise_coverage + 1e-3,
            "{m:?}: coverage {coverage}"
        );
        assert_eq!(shape.circle, sphere.circle);
    }
}

#[test]
fn shading_normals_is_deterministic_for_a_seed() {
    let lighting = shipped_lighting();
    let normals = rasterize(&Shape::torus(), &ShapeSpec::Torus.pose(), 32, 2).unwrap();
    let m = material(0.3, 0.1, 0.05);
    let q = Quality::default();
    let a = render_normals(
        &lighting,
        &m,
        &View::default(),
        &normals,
        &q,
        &mut Rng::new(9),
    );
    let b = render_normals(
        &lighting,
        &m,
        &View::default(),
        &normals,
        &q,
        &mut Rng::new(9),
    );
    assert_eq!(a.luminance, b.luminance);
    assert!(a.luminance.iter().any(|&v| v > 0.0));
    for i in 0..32 * 32 {
        let covered = normals.coverage(i / 32, i % 32);
        assert_eq!(a.coverage[i], covered);
        assert!(covered > 0.0 || a.luminance[i] == 0.0);
    }
}

#[test]
fn torus_normals_are_the_exact_gradient() {
    let (major, minor) = (1.0, 0.4);
    let size = 48;
    let normals = rasterize(&Shape::Torus { major, minor }, &Pose::identity(), size, 1).unwrap();
    let grid = Grid::new(size);
    let mut seen = 0;
    for row in 0..size {
        for col in 0..size {
            let (x, y) = grid.pixel(row, col).centre;
            // The shape frame is the camera's scaled by the bounding radius.
            let (px, py) = (x * (major + minor), y * (major + minor));
            let rho = px.hypot(py);
            let q = rho - major;
            let expected = (q.abs() < minor).then(|| {
                let z = (minor * minor - q * q).sqrt();
                Vec3::new(q * px / rho, q * py / rho, z) * (1.0 / minor)
            });
            match (normals.at(row, col), expected) {
                (Some(found), Some(e)) => {
                    seen += 1;
                    assert!(close(found, e, 1e-6), "({row}, {col}): {found:?} vs {e:?}");
                }
                (None, None) => {}
                (found, e) if (q.abs() - minor).abs() < 1e-9 => {
                    assert!(found.is_some() || e.is_none())
                }
                (found, e) => panic!("({row}, {col}): {found:?} vs {e:?}"),
            }
        }
    }
    assert!(seen > 500, "{seen}");
    assert!(normals.at(size / 2, size / 2).is_none(), "the hole");
}

#[test]
fn a_round_superquadric_is_the_sphere_in_any_pose() {
    let ball = Shape::Superquadric {
        axes: [1.0; 3],
        exponents: [1.0, 1.0],
    };
    let mut rng = Rng::new(11);
    let sphere = rasterize(&Shape::Sphere, &Pose::identity(), 32, 1).unwrap();
    for _ in 0..3 {
        let pose = Pose::random(&mut rng);
        let shape = rasterize(&ball, &pose, 32, 1).unwrap();
        for i in 0..32 * 32 {
            let (row, col) = (i / 32, i % 32);
            if let (Some(a), Some(b)) = (shape.at(row, col), sphere.at(row, col)) {
                // The fit leaves 0.1 % to spare: compare away from the limb.
                let b = Vec3::new(f64::from(b[0]), f64::from(b[1]), f64::from(b[2]));
                assert!(b.z < 0.3 || close(a, b, 0.01), "({row}, {col})");
            }
        }
    }
}

#[test]
fn a_turned_ellipsoid_is_the_ellipsoid_of_turned_axes() {
    let along_x = Shape::Superquadric {
        axes: [1.0, 0.5, 0.6],
        exponents: [1.0, 1.0],
    };
    let along_y = Shape::Superquadric {
        axes: [0.5, 1.0, 0.6],
        exponents: [1.0, 1.0],
    };
    let a = rasterize(&along_x, &Pose::from_euler_deg(0.0, 0.0, 90.0), 32, 2).unwrap();
    let b = rasterize(&along_y, &Pose::identity(), 32, 2).unwrap();
    for i in 0..32 * 32 {
        let (row, col) = (i / 32, i % 32);
        assert!((a.coverage(row, col) - b.coverage(row, col)).abs() < 1e-6);
        if let (Some(x), Some(y)) = (a.at(row, col), b.at(row, col)) {
            let y = Vec3::new(f64::from(y[0]), f64::from(y[1]), f64::from(y[2]));
            assert!(close(x, y, 1e-5), "({row}, {col}): {x:?} vs {y:?}");
        }
    }
}

/// Every object pixel a unit normal facing the camera; nothing outside the sphere's
/// circle (the fit); some of the frame covered.
fn assert_fits(normals: &Normals, least: f64) {
    let size = normals.size();
    let grid = Grid::new(size);
    let mut covered = 0.0;
    for row in 0..size {
        for col in 0..size {
            let c = normals.coverage(row, col);
            covered += f64::from(c);
            let (x, y) = grid.pixel(row, col).centre;
            if x.hypot(y) > 1.0 + grid.scale {
                assert_eq!(c, 0.0, "({row}, {col}) outside the circle");
            }
            if let Some(n) = normals.at(row, col) {
                let length = n.iter().map(|v| v * v).sum::<f32>().sqrt();
                assert!((length - 1.0).abs() < 1e-5 && n[2] >= 0.0, "{n:?}");
                assert!(c > 0.0);
            }
        }
    }
    let fraction = covered / (size * size) as f64;
    assert!(fraction > least, "covers {fraction}");
}

#[test]
fn every_analytic_shape_fits_the_frame_in_any_pose() {
    let mut rng = Rng::new(2);
    let shapes = [
        Shape::torus(),
        Shape::superquadric(),
        Shape::capsule(),
        Shape::Blob(Blob::seeded(4, 4)),
    ];
    for shape in &shapes {
        for _ in 0..2 {
            let normals = rasterize(shape, &Pose::random(&mut rng), 24, 2).unwrap();
            assert_fits(&normals, 0.1);
        }
    }
}

#[test]
fn random_poses_are_rotations() {
    let mut rng = Rng::new(1);
    for _ in 0..20 {
        let pose = Pose::random(&mut rng);
        let axes = [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)];
        let [x, y, z] = axes.map(|(a, b, c)| pose.apply(Vec3::new(a, b, c)));
        let cross = Vec3::new(
            x.y * y.z - x.z * y.y,
            x.z * y.x - x.x * y.z,
            x.x * y.y - x.y * y.x,
        );
        assert!((x.dot(x) - 1.0).abs() < 1e-12 && x.dot(y).abs() < 1e-12);
        assert!((cross - z).dot(cross - z) < 1e-20, "right-handed");
        let back = pose.invert(pose.apply(Vec3::new(0.3, -0.2, 0.9)));
        assert!((back - Vec3::new(0.3, -0.2, 0.9)).dot(back - Vec3::new(0.3, -0.2, 0.9)) < 1e-24);
    }
}

#[test]
fn own_maps_are_checked() {
    let ok = Normals::new(1, vec![[0.0, 0.6, 0.8]], vec![0.5]).unwrap();
    assert_eq!(ok.at(0, 0), Some([0.0, 0.6, 0.8]));
    assert!(Normals::new(2, vec![[0.0; 3]], vec![0.0]).is_err());
    assert!(Normals::new(1, vec![[0.0, 0.0, 0.5]], vec![1.0]).is_err());
    assert!(Normals::new(1, vec![[0.0, 0.0, -1.0]], vec![1.0]).is_err());
    assert!(Normals::new(1, vec![[0.0; 3]], vec![0.5]).is_err());
    assert!(Normals::new(1, vec![[0.0, 0.0, 1.0]], vec![f32::NAN]).is_err());
}

#[test]
fn blobs_are_seeded() {
    let a = Blob::seeded(7, 4);
    assert_eq!(a, Blob::seeded(7, 4));
    assert_ne!(a, Blob::seeded(8, 4));
    let pose = Pose::identity();
    let first = rasterize(&Shape::Blob(a.clone()), &pose, 24, 2).unwrap();
    assert_eq!(first, rasterize(&Shape::Blob(a), &pose, 24, 2).unwrap());
}

#[test]
fn bad_parameters_are_refused() {
    let torus = Shape::Torus {
        major: 0.2,
        minor: 0.5,
    };
    let pose = Pose::identity();
    assert!(matches!(
        rasterize(&torus, &pose, 8, 1),
        Err(ShapeError::Parameter(_))
    ));
    let box_ = Shape::Superquadric {
        axes: [1.0; 3],
        exponents: [0.0, 1.0],
    };
    assert!(matches!(
        rasterize(&box_, &pose, 8, 1),
        Err(ShapeError::Parameter(_))
    ));
    let nan = Shape::Capsule {
        half_length: f64::NAN,
        radius: 1.0,
    };
    assert!(matches!(
        rasterize(&nan, &pose, 8, 1),
        Err(ShapeError::Parameter(_))
    ));
    assert!(matches!(
        rasterize(&Shape::Sphere, &pose, 0, 1),
        Err(ShapeError::Size { .. })
    ));
    assert!(matches!(
        rasterize(&Shape::Sphere, &pose, 8, 17),
        Err(ShapeError::Size { .. })
    ));
}

#[test]
fn shape_specs_parse() {
    let parse = |s: &str| s.parse::<ShapeSpec>();
    assert_eq!(parse("sphere").unwrap(), ShapeSpec::Sphere);
    assert_eq!(parse("torus").unwrap(), ShapeSpec::Torus);
    assert_eq!(parse("blob").unwrap(), ShapeSpec::Blob);
    assert_eq!(
        parse("mesh:a/b.obj").unwrap(),
        ShapeSpec::Mesh(PathBuf::from("a/b.obj"))
    );
    assert!(parse("mesh:").is_err() && parse("cube").is_err());
    assert_eq!(ShapeSpec::default(), ShapeSpec::Sphere);
}

#[test]
fn normal_maps_round_trip_through_the_cores_reader() {
    let normals = rasterize(&Shape::torus(), &ShapeSpec::Torus.pose(), 32, 2).unwrap();
    let png = normals.to_png().unwrap();
    let map = NormalMap::from_png(&png, &Limits::default()).unwrap();
    assert_eq!((map.width(), map.height()), (32, 32));
    for row in 0..32 {
        for col in 0..32 {
            match (normals.at(row, col), map.at(row, col)) {
                (Some(a), Some(b)) => {
                    let b = Vec3::new(f64::from(b[0]), f64::from(b[1]), f64::from(b[2]));
                    assert!(close(a, b, 1e-4), "({row}, {col})");
                }
                (None, None) => {}
                (a, b) => panic!("({row}, {col}): {a:?} vs {b:?}"),
            }
        }
    }
    let back = Normals::from_map(&map).unwrap();
    assert_eq!(back.size(), 32);
    assert_eq!(back.at(3, 3), map.at(3, 3));
}

/// A UV sphere of radius 2 centred at (1, 0, 0) as OBJ text (with normals when asked):
/// `rings` × `segments` vertices plus the poles.
fn uv_sphere_obj(rings: usize, segments: usize, normals: bool) -> String {
    let mut text = String::from("# uv sphere\no ball\n");
    let mut points = vec![[0.0, 0.0, 1.0]];
    for i in 1..rings {
        let theta = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..segments {
            let phi = 2.0 * std::f64::consts::PI * j as f64 / segments as f64;
            points.push([
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            ]);
        }
    }
    points.push([0.0, 0.0, -1.0]);
    for p in &points {
        let q = p.map(|c| f64::from(c as f32));
        text.push_str(&format!(
            "v {} {} {}\n",
            2.0 * q[0] + 1.0,
            2.0 * q[1],
            2.0 * q[2]
        ));
        if normals {
            text.push_str(&format!("vn {} {} {}\n", q[0], q[1], q[2]));
        }
    }
    let ring = |i: usize, j: usize| 2 + (i - 1) * segments + j % segments;
    let last = points.len();
    let corner = |v: usize| {
        if normals {
            format!("{v}//{v}")
        } else {
            format!("{v}")
        }
    };
    for j in 0..segments {
        text.push_str(&format!(
            "f {} {} {}\n",
            corner(1),
            corner(ring(1, j)),
            corner(ring(1, j + 1))
        ));
        let bottom = [last, ring(rings - 1, j + 1), ring(rings - 1, j)];
        text.push_str(&format!(
            "f {} {} {}\n",
            corner(bottom[0]),
            corner(bottom[1]),
            corner(bottom[2])
        ));
    }
    for i in 1..rings - 1 {
        for j in 0..segments {
            let quad = [
                ring(i, j),
                ring(i + 1, j),
                ring(i + 1, j + 1),
                ring(i, j + 1),
            ];
            let quad = quad.map(corner);
            text.push_str(&format!(
                "f {} {} {} {}\n",
                quad[0], quad[1], quad[2], quad[3]
            ));
        }
    }
    text
}

#[test]
fn a_fine_mesh_sphere_is_the_sphere() {
    let limits = MeshLimits::default();
    let sphere = rasterize(&Shape::Sphere, &Pose::identity(), 32, 2).unwrap();
    for with_normals in [true, false] {
        let mesh = parse_obj(uv_sphere_obj(48, 96, with_normals).as_bytes(), &limits).unwrap();
        assert_eq!(mesh.vertex_count(), 47 * 96 + 2);
        let pose = Pose::from_euler_deg(30.0, 10.0, 0.0);
        let shape = rasterize(&Shape::Mesh(mesh), &pose, 32, 2).unwrap();
        let mut worst: f64 = 0.0;
        for i in 0..32 * 32 {
            let (row, col) = (i / 32, i % 32);
            assert!((shape.coverage(row, col) - sphere.coverage(row, col)).abs() <= 0.5);
            if sphere.coverage(row, col) == 1.0 && shape.coverage(row, col) == 1.0 {
                let (a, b) = (shape.at(row, col).unwrap(), sphere.at(row, col).unwrap());
                let b = Vec3::new(f64::from(b[0]), f64::from(b[1]), f64::from(b[2]));
                let d = Vec3::new(f64::from(a[0]), f64::from(a[1]), f64::from(a[2])) - b;
                worst = worst.max(d.dot(d).sqrt());
            }
        }
        assert!(worst < 0.05, "normals={with_normals}: {worst}");
        // Sub-pixel coverage: the mesh's silhouette covers the disc's area.
        let area = |m: &Normals| {
            (0..32 * 32)
                .map(|i| f64::from(m.coverage(i / 32, i % 32)))
                .sum::<f64>()
        };
        let (mesh_area, disc) = (area(&shape), area(&sphere));
        assert!(
            (mesh_area / disc - 1.0).abs() < 0.01,
            "{mesh_area} vs {disc}"
        );
    }
}

const CUBE: &str = "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n\
f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 3 4 8 7\nf 2 3 7 6\nf 4 1 5 8\n";

#[test]
fn a_cube_keeps_its_creases() {
    let mesh = parse_obj(CUBE.as_bytes(), &MeshLimits::default()).unwrap();
    assert_eq!(mesh.triangle_count(), 12);
    let face_on = rasterize(&Shape::Mesh(mesh.clone()), &Pose::identity(), 32, 2).unwrap();
    assert!(close(
        face_on.at(16, 16).unwrap(),
        Vec3::new(0.0, 0.0, 1.0),
        1e-6
    ));
    let turned = rasterize(
        &Shape::Mesh(mesh),
        &Pose::from_euler_deg(35.0, 45.0, 0.0),
        32,
        2,
    )
    .unwrap();
    let mut distinct: Vec<[f32; 3]> = Vec::new();
    for i in 0..32 * 32 {
        if turned.coverage(i / 32, i % 32) == 1.0 {
            let n = turned.at(i / 32, i % 32).unwrap();
            let new = distinct.iter().all(|d| {
                !close(
                    *d,
                    Vec3::new(f64::from(n[0]), f64::from(n[1]), f64::from(n[2])),
                    1e-3,
                )
            });
            if new {
                distinct.push(n);
            }
        }
    }
    assert!((3..=6).contains(&distinct.len()), "{distinct:?}");
}

/// The UV sphere's OBJ as PLY: ASCII, or binary (little- or big-endian), with normals.
fn as_ply(obj: &str, format: &str) -> Vec<u8> {
    let mesh_lines = obj.lines();
    let vertices: Vec<Vec<f32>> = mesh_lines
        .clone()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
        .collect();
    let normals: Vec<Vec<f32>> = mesh_lines
        .clone()
        .filter_map(|l| l.strip_prefix("vn "))
        .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
        .collect();
    let faces: Vec<Vec<i32>> = mesh_lines
        .filter_map(|l| l.strip_prefix("f "))
        .map(|l| {
            l.split_whitespace()
                .map(|c| c.split('/').next().unwrap().parse::<i32>().unwrap() - 1)
                .collect()
        })
        .collect();
    let mut out = format!(
        "ply\nformat {format} 1.0\ncomment test\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty uchar red\n\
         element face {}\nproperty list uchar int vertex_indices\nelement edge 1\nproperty int a\nproperty int b\nend_header\n",
        vertices.len(),
        faces.len()
    )
    .into_bytes();
    let big = format == "binary_big_endian";
    let put = |bytes: &[u8], out: &mut Vec<u8>| {
        let mut b = bytes.to_vec();
        if big {
            b.reverse();
        }
        out.extend_from_slice(&b);
    };
    for (v, n) in vertices.iter().zip(&normals) {
        let row = [v[0], v[1], v[2], n[0], n[1], n[2]];
        match format {
            "ascii" => out.extend_from_slice(
                format!(
                    "{} {} {} {} {} {} 7\n",
                    row[0], row[1], row[2], row[3], row[4], row[5]
                )
                .as_bytes(),
            ),
            _ => {
                for value in row {
                    put(&value.to_le_bytes(), &mut out);
                }
                out.push(7);
            }
        }
    }
    for f in &faces {
        match format {
            "ascii" => {
                let list: Vec<String> = f.iter().map(i32::to_string).collect();
                out.extend_from_slice(format!("{} {}\n", f.len(), list.join(" ")).as_bytes());
            }
            _ => {
                out.push(f.len() as u8);
                for &i in f {
                    put(&i.to_le_bytes(), &mut out);
                }
            }
        }
    }
    match format {
        "ascii" => out.extend_from_slice(b"0 1\n"),
        _ => {
            put(&0i32.to_le_bytes(), &mut out);
            put(&1i32.to_le_bytes(), &mut out);
        }
    }
    out
}

#[test]
fn ply_meshes_ascii_and_binary_read_as_the_obj() {
    let limits = MeshLimits::default();
    let obj = uv_sphere_obj(12, 24, true);
    let from_obj = parse_obj(obj.as_bytes(), &limits).unwrap();
    let pose = Pose::from_euler_deg(20.0, 0.0, 0.0);
    let expected = rasterize(&Shape::Mesh(from_obj), &pose, 24, 2).unwrap();
    for format in ["ascii", "binary_little_endian", "binary_big_endian"] {
        let mesh = parse_ply(&as_ply(&obj, format), &limits).unwrap();
        assert_eq!(mesh.vertex_count(), 11 * 24 + 2, "{format}");
        let found = rasterize(&Shape::Mesh(mesh), &pose, 24, 2).unwrap();
        for i in 0..24 * 24 {
            let (row, col) = (i / 24, i % 24);
            assert_eq!(
                found.coverage(row, col),
                expected.coverage(row, col),
                "{format}"
            );
            if let (Some(a), Some(b)) = (found.at(row, col), expected.at(row, col)) {
                let b = Vec3::new(f64::from(b[0]), f64::from(b[1]), f64::from(b[2]));
                assert!(close(a, b, 1e-6), "{format} ({row}, {col})");
            }
        }
    }
}

#[test]
fn bad_mesh_files_are_typed_errors() {
    let limits = MeshLimits::default();
    let obj_cases = [
        "v 1 2\nf 1 1 1\n",
        "v 1 2 3\nv 1 2 4\nf 1 2 3\n",
        "v 1 2 3\nv 1 2 4\nv 0 0 0\nf 1 2\n",
        "v 1 2 nan\n",
        "v 1 2 3\nf 0 1 1\n",
        "",
        "v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 3\n",
    ];
    for case in obj_cases {
        assert!(parse_obj(case.as_bytes(), &limits).is_err(), "{case:?}");
    }
    assert!(parse_obj(&[0xff, 0xfe, 0x00], &limits).is_err());
    let small = MeshLimits {
        vertices: 2,
        ..limits
    };
    let too_many = parse_obj(CUBE.as_bytes(), &small);
    assert!(
        matches!(too_many, Err(ShapeError::TooLarge(_))),
        "{too_many:?}"
    );
    let few_bytes = MeshLimits {
        bytes: 16,
        ..limits
    };
    let too_long = parse_obj(CUBE.as_bytes(), &few_bytes);
    assert!(
        matches!(too_long, Err(ShapeError::TooLarge(_))),
        "{too_long:?}"
    );
    let ply_cases: [&[u8]; 6] = [
        b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n0 0 0\n",
        b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n3 0 1 2\n",
        b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n",
        b"plx\nformat ascii 1.0\nend_header\n",
        b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n\x00\x00",
    ];
    for case in ply_cases {
        assert!(
            parse_ply(case, &limits).is_err(),
            "{:?}",
            String::from_utf8_lossy(case)
        );
    }
    let missing = load_mesh(Path::new("/nonexistent/mesh.obj"), &limits);
    assert!(matches!(missing, Err(ShapeError::Io { .. })));
    let wrong = load_mesh(Path::new("mesh.stl"), &limits);
    assert!(matches!(wrong, Err(ShapeError::Format(_))));
}

#[test]
fn mangled_mesh_files_never_panic() {
    let limits = MeshLimits::default();
    let obj = uv_sphere_obj(4, 6, true).into_bytes();
    let ply = as_ply(
        &String::from_utf8(obj.clone()).unwrap(),
        "binary_little_endian",
    );
    let mut rng = Rng::new(17);
    for round in 0..300 {
        let mut bytes = if round % 2 == 0 {
            obj.clone()
        } else {
            ply.clone()
        };
        for _ in 0..1 + rng.below(8) {
            let i = rng.below(bytes.len() as u64) as usize;
            bytes[i] = rng.below(256) as u8;
        }
        let cut = rng.below(bytes.len() as u64 + 1) as usize;
        let bytes = if round % 3 == 0 {
            &bytes[..cut]
        } else {
            &bytes[..]
        };
        let parsed = match round % 2 {
            0 => parse_obj(bytes, &limits),
            _ => parse_ply(bytes, &limits),
        };
        if let Ok(mesh) = parsed {
            rasterize(&Shape::Mesh(mesh), &Pose::identity(), 8, 1).unwrap();
        }
    }
}
