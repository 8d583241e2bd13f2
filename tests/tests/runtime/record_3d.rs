//! 3D runs (`Trajectory::glb`, `write_3d`): what the robot files say their
//! links look like (`Scene::VISUALS`, from URDF `<visual>` and MJCF
//! `<geom>`, worked out by hand), and the `.glb` read back as glTF 2.0
//! defines it: its header and chunks, one animated node per body whose
//! keys are the recorded samples (to `f32`), decimated to the display rate,
//! stand-ins where a file's mesh is not on disk. The browser's view of it
//! is `examples/tests/viewer.rs`.

use joint_runtime::Scene;
use joint_runtime::nalgebra::{UnitQuaternion, Vector3};
use joint_runtime::record::{Glb, GltfOptions, Trajectory};
use joint_runtime::relative::{TreeSimulation, TreeState};
use joint_runtime::robot::{Shape, Visual};
use joint_tests::scenes::hanging_rods;
use serde_json::Value;

/// Every geom type MuJoCo draws (`tests/data/mjcf/shapes.xml`).
#[derive(Scene)]
#[scene(mjcf = "data/mjcf/shapes.xml", coordinates = both)]
struct Shapes;

/// The Panda from its URDF, its meshes in `tests/data/robots/example-robot-data`.
#[derive(Scene)]
#[scene(urdf = "data/robots/panda.urdf", coordinates = both, mimic = independent)]
struct Panda;

/// The UR5 from its URDF, whose meshes are not in the repository.
#[derive(Scene)]
#[scene(urdf = "data/robots/ur5.urdf", coordinates = both)]
struct Ur5;

/// Every joint at its zero, at rest.
fn rest<const NQ: usize, const NV: usize>() -> TreeState<NQ, NV> {
    TreeState { q: joint_runtime::nalgebra::SVector::zeros(), v: joint_runtime::nalgebra::SVector::zeros(), t: 0.0 }
}

fn close(a: [f64; 3], b: [f64; 3]) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12)
}

#[test]
fn mjcf_geoms_on_their_bodies() {
    let v = Shapes::VISUALS;
    assert_eq!(v.len(), 7, "the group-3 and the transparent geoms are left out: {v:#?}");
    // The floor, on the ground: MJCF's zero size is an infinite plane.
    assert_eq!((v[0].body, v[0].shape, v[0].rgba), (None, Shape::Plane([0.0, 0.0]), None));
    // `fromto` from the link's origin (1 m up) down 1 m: centred on the arm's centre, z turned down.
    let capsule = &v[1];
    assert_eq!(
        (capsule.body, capsule.shape, capsule.rgba),
        (Some(0), Shape::Capsule(0.05, 0.5), Some([0.0, 0.0, 1.0, 1.0]))
    );
    assert!(close(capsule.origin, [0.0; 3]) && close(capsule.rotation[2], [0.0, 0.0, -1.0]), "{capsule:?}");
    // The material's colour; the geom's own, transparency kept.
    assert_eq!((v[2].shape, v[2].rgba), (Shape::Box([0.1, 0.2, 0.3]), Some([1.0, 0.0, 0.0, 1.0])));
    assert!(close(v[2].origin, [0.0, 0.0, -0.5]));
    assert_eq!((v[3].shape, v[3].rgba), (Shape::Sphere(0.07), Some([0.0, 1.0, 0.0, 0.5])));
    assert!(close(v[3].origin, [0.1, 0.0, 0.5]));
    // `euler` of a quarter turn about x: the cylinder's axis along −y.
    assert_eq!(v[4].shape, Shape::Cylinder(0.02, 0.1));
    assert!(close(v[4].origin, [0.0, 0.1, 0.5]) && close(v[4].rotation[2], [0.0, -1.0, 0.0]), "{:?}", v[4]);
    assert_eq!(v[5].shape, Shape::Ellipsoid([0.1, 0.2, 0.3]));
    // The mesh under the compiler's `meshdir`, found on disk, with its scale.
    let Shape::Mesh { file, scale } = v[6].shape else { panic!("{:?}", v[6]) };
    assert!(std::path::Path::new(file).is_absolute() && file.ends_with("tests/data/mjcf/meshes/tetra.stl"), "{file}");
    assert_eq!(scale, [2.0; 3]);
}

#[test]
fn urdf_visuals_with_their_meshes_where_on_disk() {
    // The Panda's eleven `<visual>`s (links 0–7, hand, fingers), every mesh found by its package.
    assert_eq!(Panda::VISUALS.len(), 11);
    assert_eq!(Panda::VISUALS[0].body, None, "link0 is welded to the ground");
    for v in &Panda::VISUALS {
        let Shape::Mesh { file, .. } = v.shape else { panic!("{v:?}") };
        assert!(std::path::Path::new(file).is_file(), "{file}");
    }
    // The UR5's meshes are not in the repository: their names as written.
    assert!(Ur5::VISUALS.iter().all(|v| matches!(v.shape, Shape::Mesh { file, .. } if file.starts_with("package://"))));
}

/// The GLB's JSON and binary chunks, checked as the glTF 2.0 container.
fn chunks(glb: &Glb) -> (Value, Vec<u8>) {
    let b = &glb.bytes;
    let word = |at: usize| u32::from_le_bytes(b[at..at + 4].try_into().unwrap()) as usize;
    assert_eq!((&b[0..4], word(4), word(8)), (&b"glTF"[..], 2, b.len()));
    let json_length = word(12);
    assert_eq!((&b[16..20], json_length % 4), (&b"JSON"[..], 0));
    let json: Value = serde_json::from_slice(&b[20..20 + json_length]).expect("the JSON chunk parses");
    let at = 20 + json_length;
    assert_eq!(&b[at + 4..at + 8], b"BIN\0");
    let bin = b[at + 8..at + 8 + word(at)].to_vec();
    assert_eq!(json["buffers"][0]["byteLength"].as_u64(), Some(bin.len() as u64));
    (json, bin)
}

/// Accessor `index`'s floats.
fn floats(json: &Value, bin: &[u8], index: &Value) -> Vec<f32> {
    let a = &json["accessors"][index.as_u64().unwrap() as usize];
    assert_eq!(a["componentType"], 5126);
    let view = &json["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
    let start = view["byteOffset"].as_u64().unwrap() as usize;
    let length = view["byteLength"].as_u64().unwrap() as usize;
    bin[start..start + length].chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect()
}

#[test]
fn glb_animates_each_body_by_its_samples() {
    // 3 s recorded at 1 kHz, shown at 50 frames a second: 151 frames, the last sample kept.
    let mut run = Trajectory::new(&super::record::rods());
    for k in 0..=3000 {
        let t = 1e-3 * f64::from(k);
        let mut state = hanging_rods([0.5 * t.sin(), 3.0 * t]);
        state.t = t;
        run.record(&state);
    }
    let glb = run.glb(&GltfOptions::default());
    assert_eq!((glb.frames, glb.missing.len()), (151, 0));
    let (json, bin) = chunks(&glb);
    assert_eq!(json["asset"]["version"], "2.0");
    let animation = &json["animations"][0];
    let channels = animation["channels"].as_array().unwrap();
    assert_eq!(channels.len(), 4, "translation and rotation of both bodies");
    for c in channels {
        let sampler = &animation["samplers"][c["sampler"].as_u64().unwrap() as usize];
        let node = &json["nodes"][c["target"]["node"].as_u64().unwrap() as usize];
        let body = ["upper", "lower"].iter().position(|n| node["name"] == *n).expect("a body's node");
        let times = floats(&json, &bin, &sampler["input"]);
        let values = floats(&json, &bin, &sampler["output"]);
        assert_eq!((times.len(), times[150]), (151, 3.0));
        for (f, t) in times.iter().enumerate() {
            let sample = &run.samples()[(f64::from(*t) * 1e3).round() as usize];
            assert!((sample.t - f64::from(*t)).abs() < 1e-6);
            let b = &sample.bodies[body];
            if c["target"]["path"] == "translation" {
                let key = Vector3::new(values[3 * f], values[3 * f + 1], values[3 * f + 2]).map(f64::from);
                assert!((key - b.r).norm() < 1e-6, "{key} against {}", b.r);
            } else {
                // The key's quaternion (x, y, z, w) turns as the body does, its sign kept continuous.
                let q = &values[4 * f..4 * f + 4];
                let key = UnitQuaternion::from_quaternion(
                    joint_runtime::nalgebra::Quaternion::new(q[3], q[0], q[1], q[2]).cast::<f64>(),
                );
                assert!(key.angle_to(&b.rotation()) < 1e-6);
                if f > 0 {
                    let before = &values[4 * f - 4..4 * f];
                    assert!(q.iter().zip(before).map(|(a, b)| a * b).sum::<f32>() > 0.0);
                }
            }
        }
    }
}

#[test]
fn files_meshes_drawn_or_stood_in_for() {
    let panda = TreeSimulation::new(&Panda).unwrap();
    let ur5 = TreeSimulation::new(&Ur5).unwrap();
    let mut arm = Trajectory::new(&Panda);
    let mut other = Trajectory::new(&Ur5);
    for k in 0..3 {
        let t = 0.1 * f64::from(k);
        arm.record(&joint_runtime::SystemState { t, ..panda.system_state(&rest()) });
        other.record(&joint_runtime::SystemState { t, ..ur5.system_state(&rest()) });
    }
    let (json, _) = chunks(&arm.glb(&GltfOptions::default()));
    let names: Vec<&str> = json["meshes"].as_array().unwrap().iter().map(|m| m["name"].as_str().unwrap()).collect();
    assert!(names.contains(&"ground shape 0") && names.contains(&"panda_link7 shape 7"), "{names:?}");
    assert!(!names.iter().any(|n| n.contains("stand-in")));
    // The UR5's seven meshes are missing: named, and each moving body a stand-in.
    let glb = other.glb(&GltfOptions::default());
    assert_eq!(glb.missing.len(), 7, "{:?}", glb.missing);
    let (json, _) = chunks(&glb);
    let stand_ins =
        json["meshes"].as_array().unwrap().iter().filter(|m| m["name"].as_str().unwrap().contains("stand-in"));
    assert!(stand_ins.count() >= 6);
}

#[test]
fn every_geom_type_in_the_file() {
    let sim = TreeSimulation::new(&Shapes).unwrap();
    let mut run = Trajectory::new(&Shapes);
    run.record(&sim.system_state(&rest()));
    let glb = run.glb(&GltfOptions::default().with_title("shapes"));
    assert!(glb.missing.is_empty(), "{:?}", glb.missing);
    let (json, bin) = chunks(&glb);
    assert_eq!(json["asset"]["extras"]["title"], "shapes");
    // The tetrahedron's mesh, scaled twice: its corners 0.2 from the origin.
    let mesh = json["meshes"].as_array().unwrap().iter().find(|m| m["name"] == "arm shape 6").expect("the mesh");
    let positions = floats(&json, &bin, &mesh["primitives"][0]["attributes"]["POSITION"]);
    assert_eq!(positions.len(), 12, "four corners, welded");
    assert!((positions.iter().fold(0f32, |m, x| m.max(*x)) - 0.2).abs() < 1e-6);
    let _: &[Visual] = &Shapes::VISUALS;
}
