//! Scene files: the shipped scenes load; errors name the file, line and field.

use hilcam_core::scene::{SceneError, load};
use std::path::{Path, PathBuf};

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

const PLATE_OBJ: &str = "mtllib p.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl paint\nf 1 2 3\n";
const PLATE_MTL: &str = "newmtl paint\nKd 0.5 0.5 0.5\n";

fn fixture() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "p.obj", PLATE_OBJ);
    write(dir.path(), "p.mtl", PLATE_MTL);
    dir
}

const GOOD: &str = r#"
[[mesh]]
obj = "p.obj"

[materials.paint]
model = "lambert"
rho = 0.5

[camera]
width = 64
height = 48
pitch_um = 10.0
focal_mm = 20.0
"#;

#[test]
fn shipped_scenes_load() {
    for s in ["scenes/plate.toml", "scenes/sphere.toml"] {
        let scene = load(Path::new(s)).unwrap_or_else(|e| panic!("{e}"));
        assert!(!scene.mesh.indices.is_empty());
    }
}

#[test]
fn a_minimal_scene_loads_with_defaults() {
    let dir = fixture();
    let scene = load(&write(dir.path(), "s.toml", GOOD)).unwrap();
    assert_eq!(scene.mesh.indices.len(), 1);
    assert_eq!(scene.sun_irradiance, 593.1);
    assert_eq!(scene.background, 0.0);
    assert_eq!(scene.camera.width, 64);
    // A budget with a fraction is read exactly.
    let frac = load(&write(dir.path(), "f.toml", &format!("{GOOD}\n[render]\nspp = 1.25\n"))).unwrap();
    assert_eq!(frac.render.spp.milli(), 1250);
}

fn error_of(text: &str) -> String {
    let dir = fixture();
    let p = write(dir.path(), "s.toml", text);
    match load(&p) {
        Ok(_) => panic!("expected an error"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_material_value_names_file_line_and_field() {
    let e = error_of(&GOOD.replace("rho = 0.5", "rho = 1.5"));
    assert!(e.contains("s.toml:5:") && e.contains("materials.paint") && e.contains("rho"), "{e}");
}

#[test]
fn unmapped_mtl_material_is_named() {
    // Neither a [materials.paint] table nor a `newmtl paint` in the MTL: tobj gives the
    // face the material `default`, which has neither either.
    let dir = fixture();
    write(dir.path(), "p.mtl", "newmtl other\nKd 0.5 0.5 0.5\n");
    let p = write(dir.path(), "s.toml", &GOOD.replace("[materials.paint]", "[materials.other]"));
    let e = load(&p).err().expect("expected an error").to_string();
    assert!(e.contains("s.toml:3:") && e.contains("`default`") && e.contains("[materials.default]"), "{e}");
    assert!(e.contains("no definition in the model file"), "{e}");
    // With the MTL's own `newmtl paint`, the same scene loads: the MTL's Kd is used.
    write(dir.path(), "p.mtl", PLATE_MTL);
    let scene = load(&p).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.mesh.indices.len(), 1);
}

#[test]
fn missing_obj_and_unknown_key_and_bad_camera_are_named() {
    let e = error_of(&GOOD.replace("p.obj", "nope.obj"));
    assert!(e.contains("s.toml:3:") && e.contains("mesh[0].obj") && e.contains("nope.obj"), "{e}");
    let e = error_of(&GOOD.replace("rho = 0.5", "rho = 0.5\ncolour = 1"));
    // Unknown keys inside a material are reported at the material table's line.
    assert!(e.contains("line 5") && e.contains("colour"), "{e}");
    let e = error_of(&GOOD.replace("pitch_um = 10.0", "pitch_um = -1.0"));
    assert!(e.contains("s.toml:") && e.contains("camera.pitch_um"), "{e}");
    let e = error_of(&format!("{GOOD}\n[render]\nspp = 0\n"));
    assert!(e.contains("render.spp"), "{e}");
    let e = error_of(&format!("{GOOD}\n[render]\nspp = 1.0625\n"));
    assert!(e.contains("render.spp") && e.contains("thousandths"), "{e}");
    let e = error_of(&format!("{GOOD}\n[pose]\nposition = [0, 0, 5]\nattitude = [2, 0, 0, 0]\nsun = [0, 0, -1]\n"));
    assert!(e.contains("pose.attitude") && e.contains(":17:"), "{e}");
}

#[test]
fn io_errors_name_the_file() {
    let e = load(Path::new("/nonexistent/scene.toml")).err().unwrap();
    assert!(matches!(e, SceneError::Io { .. }) && e.to_string().contains("/nonexistent/scene.toml"));
}

/// The `[pose]` default a line of docs/scene.md's format block states for `key`:
/// `key = … # … (default [a, b, c])` → [a, b, c].
fn documented_pose_default(key: &str) -> [f64; 3] {
    let page = std::fs::read_to_string("docs/scene.md").unwrap();
    let line = page
        .lines()
        .find(|l| l.starts_with(&format!("{key} = ")) && l.contains("(default ["))
        .unwrap_or_else(|| panic!("docs/scene.md states no default for pose.{key}"));
    let list = line.split("(default [").nth(1).unwrap().split(']').next().unwrap();
    let v: Vec<f64> = list.split(',').map(|t| t.trim().replace('−', "-").parse().unwrap()).collect();
    v.try_into().unwrap()
}

/// Issue 42: a `[pose]` table that lacks `position` or `sun` takes the documented default
/// for that field (it was refused with `missing field`; the defaults held only without
/// the table).
#[test]
fn r42_a_pose_table_missing_a_field_takes_its_documented_default() {
    let (position, sun) = (documented_pose_default("position"), documented_pose_default("sun"));
    assert_eq!((position, sun), ([0.0, 0.0, 10.0], [0.0, 0.0, -1.0]), "the defaults docs/scene.md states");
    let dir = fixture();
    let load_pose = |table: &str| {
        let p = write(dir.path(), "s.toml", &format!("{GOOD}\n[pose]\n{table}"));
        load(&p).unwrap_or_else(|e| panic!("[pose] {table:?}: {e}")).pose
    };
    let only_attitude = load_pose("attitude = [0.0, 1.0, 0.0, 0.0]\n");
    assert_eq!(only_attitude.position.to_array(), position);
    assert_eq!(only_attitude.sun_dir.to_array(), sun);
    assert_eq!(only_attitude.attitude.to_array(), [1.0, 0.0, 0.0, 0.0], "x, y, z, w: a half turn about x");
    let only_position = load_pose("position = [1.0, 2.0, 30.0]\n");
    assert_eq!((only_position.position.to_array(), only_position.sun_dir.to_array()), ([1.0, 2.0, 30.0], sun));
    let only_sun = load_pose("sun = [0.0, 1.0, 0.0]\n");
    assert_eq!((only_sun.position.to_array(), only_sun.sun_dir.to_array()), (position, [0.0, 1.0, 0.0]));
    // An empty table is the absent one.
    let empty = load_pose("");
    let absent = load(&write(dir.path(), "a.toml", GOOD)).unwrap().pose;
    assert_eq!(format!("{empty:?}"), format!("{absent:?}"));
}
