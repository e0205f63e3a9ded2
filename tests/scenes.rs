//! Scene layer: built-ins, the shared scene folders, manifests, error reporting, environment
//! map sampling and texture conventions.
//!
//! Tests that need `../shared/scenes` print a `SKIP` line and pass when it is absent (CI has it).

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{Mat3, Vec2, Vec3};
use stereotrace::scene::envmap::EnvMap;
use stereotrace::scene::folder::{FolderOptions, load_folder};
use stereotrace::scene::manifest::load_manifest;
use stereotrace::scene::obj::{ObjOptions, load_obj};
use stereotrace::scene::sampling::uniform_sphere;
use stereotrace::scene::texture::srgb_to_linear;
use stereotrace::scene::*;

// ---------------------------------------------------------------------------------------------
// Helpers

fn shared_scenes() -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes");
    if p.join("README.md").is_file() {
        Some(p)
    } else {
        common::skip(&format!("{} not found; the shared-scene tests need it (CI has it)", p.display()));
        None
    }
}

struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> Self {
        static N: AtomicUsize = AtomicUsize::new(0);
        let p = std::env::temp_dir().join(format!(
            "stereotrace-scenes-{tag}-{}-{}",
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&p).unwrap();
        Self(p)
    }

    fn write(&self, name: &str, contents: impl AsRef<[u8]>) -> PathBuf {
        let p = self.0.join(name);
        std::fs::write(&p, contents).unwrap();
        p
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn build(name: &str) -> Scene {
    resolve(name).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn effects(names: &[&str]) -> EffectSet {
    names.iter().fold(EffectSet::EMPTY, |s, n| s.with(Effect::from_name(n).unwrap_or_else(|| panic!("{n}"))))
}

/// Closest distance from `p` to triangle `t` (Ericson, Real-Time Collision Detection 5.1.5).
fn point_triangle_distance(p: Vec3, [a, b, c]: [Vec3; 3]) -> f32 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (p - (a + ab * (d1 / (d1 - d3)))).length();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (p - (a + ac * (d2 / (d2 - d6)))).length();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return (p - (b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))))).length();
    }
    let denom = 1.0 / (va + vb + vc);
    (p - (a + ab * (vb * denom) + ac * (vc * denom))).length()
}

/// Smallest distance from `p` to the mesh, or `limit` if nothing is closer (AABB-culled).
fn mesh_distance(mesh: &Mesh, p: Vec3, limit: f32) -> f32 {
    let mut best = limit;
    for t in &mesh.positions {
        let lo = t[0].min(t[1]).min(t[2]) - Vec3::splat(best);
        let hi = t[0].max(t[1]).max(t[2]) + Vec3::splat(best);
        if p.cmplt(lo).any() || p.cmpgt(hi).any() {
            continue;
        }
        best = best.min(point_triangle_distance(p, *t));
    }
    best
}

/// Nearest hit distance along a ray (brute force), ignoring fully transparent materials.
fn first_hit(scene: &Scene, o: Vec3, d: Vec3) -> f32 {
    let mut best = f32::INFINITY;
    for (i, t) in scene.mesh.positions.iter().enumerate() {
        if scene.materials[scene.mesh.material[i] as usize].opacity == 0.0 {
            continue;
        }
        let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-12 {
            continue;
        }
        let s = o - t[0];
        let u = s.dot(p) / det;
        let q = s.cross(e1);
        let v = d.dot(q) / det;
        let tt = e2.dot(q) / det;
        if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && tt > 1e-4 && tt < best {
            best = tt;
        }
    }
    best
}

// ---------------------------------------------------------------------------------------------
// Built-ins

#[test]
fn every_builtin_builds_validates_and_is_listed() {
    let list = list_builtin();
    let names: Vec<&str> = list.iter().map(|b| b.name).collect();
    assert_eq!(
        names,
        [
            "cornell",
            "atrium",
            "atrium-glossy",
            "atrium-moving-light",
            "atrium-moving-object",
            "living-room",
            "living-room-glossy",
            "living-room-moving-light",
            "classroom",
            "classroom-glossy",
            "classroom-mirror",
            "courtyard"
        ]
    );
    for info in &list {
        let s = build(info.name);
        s.validate().unwrap();
        assert_eq!(s.triangle_count(), info.triangles);
        assert_eq!(s.effects, info.effects);
        assert_eq!(s.name, info.name);
        assert_eq!(s.frame_count(), 60);
        assert!(s.warnings.is_empty(), "{}: {:?}", s.name, s.warnings);
        assert_eq!(s.mesh.degenerate_count(), 0, "{}", s.name);
        assert!(s.names_kebab_case(), "{}", s.name);
        // Display names name the paper scene they stand for.
        if let Some(p) = info.paper_scene {
            assert!(info.display_name.contains(p), "{} / {p}", info.display_name);
        }
    }
    let paper: BTreeSet<&str> = list.iter().filter_map(|b| b.paper_scene).collect();
    for p in [
        "Sponza",
        "Sponza (Glossy)",
        "Sponza (Moving Light)",
        "Living Room",
        "Living Room (Glossy)",
        "Living Room (Moving Light)",
        "Classroom",
        "Classroom (Glossy)",
        "Classroom (Mirror)",
        "San Miguel",
    ] {
        assert!(paper.contains(p), "no stand-in for {p}");
    }
}

trait KebabName {
    fn names_kebab_case(&self) -> bool;
}

impl KebabName for Scene {
    fn names_kebab_case(&self) -> bool {
        !self.name.is_empty()
            && self.name.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-')
            && !self.name.starts_with('-')
            && !self.name.ends_with('-')
    }
}

#[test]
fn builtin_triangle_counts_are_in_range() {
    let ranges: [(&str, usize, usize); 5] = [
        ("cornell", 20, 100),
        ("atrium", 100_000, 400_000),
        ("living-room", 100_000, 300_000),
        ("classroom", 100_000, 300_000),
        ("courtyard", 250_000, 900_000),
    ];
    for (name, lo, hi) in ranges {
        let n = build(name).triangle_count();
        assert!((lo..=hi).contains(&n), "{name}: {n} triangles, expected {lo}..={hi}");
    }
    // Variants share their base's geometry.
    for (base, variant) in [
        ("atrium", "atrium-glossy"),
        ("atrium", "atrium-moving-light"),
        ("living-room", "living-room-glossy"),
        ("living-room", "living-room-moving-light"),
        ("classroom", "classroom-glossy"),
        ("classroom", "classroom-mirror"),
    ] {
        let (a, b) = (build(base), build(variant));
        assert_eq!(a.mesh.positions, b.mesh.positions, "{variant}");
        assert_eq!(a.camera, b.camera, "{variant}");
    }
}

#[test]
fn builtins_are_deterministic() {
    for name in builtin_names() {
        let (a, b) = (build(name), build(name));
        assert!(a == b, "{name} differs between two builds");
        assert_eq!(a.fingerprint(), b.fingerprint(), "{name}");
    }
    // Fingerprints tell scenes (and variants) apart.
    let prints: BTreeSet<u64> = builtin_names().iter().map(|n| build(n).fingerprint()).collect();
    assert_eq!(prints.len(), builtin_names().len());
}

#[test]
fn builtin_effect_flags_match_their_content() {
    let expected: [(&str, &[&str]); 12] = [
        ("cornell", &["area-lights"]),
        ("atrium", &["textures", "area-lights"]),
        ("atrium-glossy", &["glossy", "textures", "area-lights"]),
        ("atrium-moving-light", &["moving-lights", "textures", "area-lights"]),
        ("atrium-moving-object", &["moving-objects", "textures", "area-lights"]),
        ("living-room", &["textures", "area-lights"]),
        ("living-room-glossy", &["glossy", "textures", "area-lights"]),
        ("living-room-moving-light", &["moving-lights", "textures", "area-lights", "point-lights"]),
        ("classroom", &["textures", "sun", "area-lights", "sky"]),
        ("classroom-glossy", &["glossy", "textures", "sun", "area-lights", "sky"]),
        ("classroom-mirror", &["mirror", "textures", "sun", "area-lights", "sky"]),
        ("courtyard", &["textures", "sun", "sky"]),
    ];
    for (name, flags) in expected {
        let s = build(name);
        assert_eq!(s.effects, effects(flags), "{name}: got {}", s.effects);
        // Flags follow the content, in both directions.
        let kinds: BTreeSet<String> =
            s.mesh.material.iter().map(|&m| format!("{:?}", s.materials[m as usize].kind)).collect();
        assert_eq!(s.effects.has(Effect::Glossy), kinds.contains("Glossy"), "{name}");
        assert_eq!(s.effects.has(Effect::Mirror), kinds.contains("Mirror"), "{name}");
        assert_eq!(s.effects.has(Effect::MovingLights), !s.lights.moving.is_empty(), "{name}");
        assert_eq!(s.effects.has(Effect::MovingObjects), !s.moving_objects.is_empty(), "{name}");
    }
    // The diffuse, static-light bases pay for nothing they do not have.
    for name in ["cornell", "atrium", "living-room", "classroom", "courtyard"] {
        let e = build(name).effects;
        for f in [
            Effect::Glossy,
            Effect::Mirror,
            Effect::MovingLights,
            Effect::MovingObjects,
            Effect::EnvMap,
            Effect::AlphaMasks,
        ] {
            assert!(!e.has(f), "{name} has {f:?}");
        }
    }
}

#[test]
fn classroom_mirror_turns_exactly_the_notice_board_into_a_mirror() {
    let (base, mirror) = (build("classroom"), build("classroom-mirror"));
    let diff: Vec<(&Material, &Material)> =
        base.materials.iter().zip(&mirror.materials).filter(|(a, b)| a != b).collect();
    assert_eq!(diff.len(), 1);
    let (a, b) = diff[0];
    assert_eq!(a.name, "notice-board");
    assert_eq!(a.kind, MaterialKind::Diffuse);
    assert_eq!(b.kind, MaterialKind::Mirror);
    assert!(b.specular.min_element() > 0.9);
}

#[test]
fn glossy_variants_make_every_reflector_glossy_and_conserve_energy() {
    for name in ["atrium-glossy", "living-room-glossy", "classroom-glossy"] {
        let s = build(name);
        for m in &s.materials {
            if m.is_emissive() {
                continue;
            }
            assert_eq!(m.kind, MaterialKind::Glossy, "{name}: {}", m.name);
            assert!((m.alpha() - 0.09).abs() < 1e-6);
            let diffuse_max = if m.albedo_texture.is_some() { m.texture_scale } else { m.albedo.max_element() };
            assert!(diffuse_max + m.specular.max_element() <= 1.0 + 1e-6, "{name}: {}", m.name);
        }
    }
}

#[test]
fn camera_paths_are_smooth_and_stay_inside_the_scenes() {
    for name in builtin_names() {
        let s = build(name);
        let poses = s.camera.poses();
        assert_eq!(poses.len(), 60);
        let steps: Vec<f32> = poses.windows(2).map(|w| (w[1].eye - w[0].eye).length()).collect();
        let travel: f32 = steps.iter().sum();
        let mean = travel / steps.len() as f32;
        // A slow, continuous observer: no jumps, no stops, bounded acceleration.
        let max = steps.iter().copied().fold(0.0, f32::max);
        let min = steps.iter().copied().fold(f32::INFINITY, f32::min);
        assert!(max <= 1.6 * mean && min >= 0.4 * mean, "{name}: steps {min}..{max}, mean {mean}");
        for w in poses.windows(3) {
            let acc = (w[2].eye - 2.0 * w[1].eye + w[0].eye).length();
            assert!(acc <= 0.2 * mean + 1e-6, "{name}: acceleration {acc} vs step {mean}");
            let turn = w[1].forward.dot(w[0].forward).clamp(-1.0, 1.0).acos().to_degrees();
            assert!(turn < 0.5, "{name}: {turn} deg in one frame");
        }
        let rotation = poses[59].forward.dot(poses[0].forward).clamp(-1.0, 1.0).acos().to_degrees();
        let bounds = s.bounds().expanded(-0.1);
        if name == "cornell" {
            assert!((0.05..0.5).contains(&travel), "{name}: travel {travel}");
        } else {
            assert!((0.5..=1.0).contains(&travel), "{name}: travel {travel}");
            assert!((2.0..=15.0).contains(&rotation), "{name}: rotation {rotation} deg");
            assert!(poses.iter().all(|p| (p.eye.y - 1.6).abs() < 0.05), "{name}: eye height");
        }
        for (f, p) in poses.iter().enumerate() {
            assert!(bounds.contains(p.eye), "{name} frame {f}: eye {} outside {:?}", p.eye, bounds);
            assert!(p.up.y > 0.95, "{name}: no roll");
            // Never inside or grazing geometry, and never staring at a wall up close.
            let clearance = mesh_distance(&s.mesh, p.eye, 0.25);
            assert!(clearance >= 0.2, "{name} frame {f}: geometry {clearance} m from the eye");
            if f % 10 == 0 || f == 59 {
                let hit = first_hit(&s, p.eye, p.forward);
                assert!(hit >= 1.0, "{name} frame {f}: view blocked at {hit} m");
            }
        }
    }
}

#[test]
fn lights_emit_and_moving_lights_fly_clear_of_geometry() {
    for name in builtin_names() {
        let s = build(name);
        let radius = 0.5 * s.bounds().extent().length();
        assert!(s.lights.approx_power(radius) > 0.0, "{name}");
        s.lights.validate().unwrap();
        for m in &s.lights.moving {
            let mut last: Option<Vec3> = None;
            for f in 0..60 {
                let (centre, size) = match m.at_frame(f as f32) {
                    PlacedLight::Point(p) => (p.position, 0.0),
                    PlacedLight::Area { triangles, .. } => {
                        let c = triangles.iter().flatten().copied().sum::<Vec3>() / (3 * triangles.len()) as f32;
                        (c, triangles.iter().flatten().map(|v| (*v - c).length()).fold(0.0, f32::max))
                    }
                };
                assert!(centre.is_finite());
                let d = mesh_distance(&s.mesh, centre, size + 0.3);
                assert!(d > size + 0.1, "{name} frame {f}: moving light {d} m from geometry");
                if let Some(l) = last {
                    assert!((centre - l).length() < 0.5, "{name}: moving light jumps");
                }
                last = Some(centre);
            }
            // It really moves.
            let at = |f: f32| match m.at_frame(f) {
                PlacedLight::Point(p) => p.position,
                PlacedLight::Area { triangles, .. } => triangles[0][0],
            };
            assert!((at(59.0) - at(0.0)).length() > 1.0, "{name}: the moving light hardly moves");
        }
    }
}

/// Moving objects never touch the static geometry: at every frame the object's bounding box
/// overlaps no static triangle's (conservative for a turning object), and it really moves.
#[test]
fn moving_objects_stay_clear_of_the_static_geometry() {
    let mut seen = 0;
    for name in builtin_names() {
        let s = build(name);
        for o in &s.moving_objects {
            seen += 1;
            let bounds = |f: f32| {
                o.at_frame(f)
                    .flatten()
                    .fold((Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)), |(lo, hi), p| {
                        (lo.min(p), hi.max(p))
                    })
            };
            for f in 0..s.frame_count() {
                let (lo, hi) = bounds(f as f32);
                for t in &s.mesh.positions {
                    let (tlo, thi) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
                    let overlap = tlo.cmple(hi).all() && thi.cmpge(lo).all();
                    assert!(!overlap, "{name}: object {:?} touches {t:?} at frame {f}", o.name);
                }
            }
            let (a, b) = (bounds(0.0).0, bounds((s.frame_count() - 1) as f32).0);
            assert!((b - a).length() > 1.0, "{name}: object {:?} hardly moves", o.name);
        }
    }
    assert!(seen > 0, "no built-in has a moving object");
}

#[test]
fn scenes_subcommand_lists_builtins() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_stereotrace")).arg("scenes").output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    for info in list_builtin() {
        let line = text.lines().find(|l| l.split_whitespace().next() == Some(info.name)).expect(info.name);
        assert!(line.contains(&info.triangles.to_string()), "{line}");
        assert!(line.contains(&info.effects.to_string()), "{line}");
    }
    let bad = std::process::Command::new(env!("CARGO_BIN_EXE_stereotrace")).args(["scenes", "nope"]).output().unwrap();
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("unknown scene 'nope'") && err.contains("atrium-moving-light"), "{err}");
}

// ---------------------------------------------------------------------------------------------
// Shared scene folders

#[test]
fn shared_scenes_load_with_readme_counts_lights_and_cameras() {
    let Some(root) = shared_scenes() else { return };
    // (folder, triangles from the README table, degenerate triangles kept, scale)
    let table = [
        ("cornell-box", 38usize, 0usize, 0.001f32),
        ("sponza", 67_405, 0, 1.0),
        ("living-room", 143_163, 190, 1.0),
        ("classroom", 103_832, 2, 1.0),
        ("bunny", 69_451, 0, 1.0),
    ];
    for (folder, triangles, degenerate, scale) in table {
        let dir = root.join(folder);
        let s = load_folder(&dir, &FolderOptions::default()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(s.triangle_count(), triangles, "{folder}");
        assert_eq!(s.mesh.degenerate_count(), degenerate, "{folder}");
        s.validate().unwrap();

        // Camera: frame 0 is camera.json's view (scaled to metres), the path is smooth and
        // stays inside the model's bounds.
        let cam: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("camera.json")).unwrap()).unwrap();
        let v = |k: &str| {
            Vec3::from_slice(&cam[k].as_array().unwrap().iter().map(|x| x.as_f64().unwrap() as f32).collect::<Vec<_>>())
        };
        let p0 = s.camera.pose(0);
        assert!((p0.eye - v("eye") * scale).length() < 1e-4 * scale.max(1.0), "{folder}");
        assert!(p0.forward.dot((v("target") - v("eye")).normalize()) > 0.99999, "{folder}");
        assert!((s.camera.vfov_deg - cam["vfov_deg"].as_f64().unwrap() as f32).abs() < 1e-4);
        let bounds = s.bounds();
        let poses = s.camera.poses();
        // (cornell-box's camera stands outside the open box, as in the source.)
        if bounds.contains(p0.eye) {
            assert!(poses.iter().all(|p| bounds.contains(p.eye)), "{folder}: camera leaves the bounds");
        }
        let steps: Vec<f32> = poses.windows(2).map(|w| (w[1].eye - w[0].eye).length()).collect();
        let mean = steps.iter().sum::<f32>() / steps.len() as f32;
        assert!(steps.iter().all(|&d| d <= 1.6 * mean && d >= 0.3 * mean), "{folder}: {steps:?}");

        // Lights as lights.json and the MTL describe them.
        let l = &s.lights;
        match folder {
            "cornell-box" => {
                assert_eq!(l.area.len(), 2);
                let m = &s.materials[s.mesh.material[l.area.triangles[0] as usize] as usize];
                assert!((m.emission - Vec3::new(20.7108, 10.8546, 2.77115)).length() < 1e-3);
                assert!(
                    (s.mesh.geometric_normal(l.area.triangles[0] as usize) - Vec3::NEG_Y).length() < 1e-4,
                    "faces down"
                );
                assert!((bounds.max.x - 0.556).abs() < 1e-4, "millimetres scaled to metres");
            }
            "sponza" => {
                assert_eq!(l.area.len(), 960);
                assert!(l.environment.is_none() && l.sun.is_none());
                // The tessellated sphere is wound outward: every emitter faces away from its centre.
                for &t in &l.area.triangles {
                    let c = s.mesh.point(t as usize, 1.0 / 3.0, 1.0 / 3.0);
                    assert!(s.mesh.geometric_normal(t as usize).dot(c - Vec3::new(0.0, 17.0, 0.0)) > 0.0);
                }
            }
            "living-room" => {
                let Some(Environment::Map(map)) = &l.environment else { panic!("no env map") };
                assert_eq!((map.texture.width, map.texture.height), (2048, 1024));
                // to_world: 90° about +Y (local +X → world −Z, local +Z → world +X).
                assert!((map.to_world * Vec3::X - Vec3::NEG_Z).length() < 1e-5);
                assert!((map.to_world * Vec3::Z - Vec3::X).length() < 1e-5);
                // lights.json's solid-angle-weighted mean radiance.
                let expected = Vec3::new(11.4249, 7.8341, 5.1251);
                assert!(
                    ((map.mean_radiance - expected) / expected).abs().max_element() < 0.01,
                    "{}",
                    map.mean_radiance
                );
                assert!(s.effects.has(Effect::EnvMap) && s.effects.has(Effect::AlphaMasks));
                assert!(l.area.is_empty());
                // Glass is kept (counts match) as a transparent cutout; leaves have a mask.
                let glass = s.materials.iter().find(|m| m.name == "Glass").unwrap();
                assert_eq!(glass.opacity, 0.0);
                let leaves = s.materials.iter().find(|m| m.name == "Leaves").unwrap();
                assert!(leaves.opacity_texture.is_some() && leaves.albedo_texture.is_some());
                assert_eq!(s.textures[leaves.opacity_texture.unwrap() as usize].channels, 1);
                let mirror = s.materials.iter().find(|m| m.name == "Mirror").unwrap();
                assert_eq!(mirror.kind, MaterialKind::Mirror);
            }
            "classroom" => {
                let sun = l.sun.expect("sun");
                assert!((sun.direction - Vec3::new(-0.8658, 0.41677, -0.27693)).length() < 1e-3);
                assert!((sun.angular_radius_deg - 0.2679 * 18.8131).abs() < 0.01);
                assert!(matches!(l.environment, Some(Environment::Sky(_))));
                assert!(s.effects.has(Effect::Sun) && s.effects.has(Effect::Sky) && s.effects.has(Effect::Mirror));
                let steel = s.materials.iter().find(|m| m.name == "ChairStainless").unwrap();
                assert_eq!(steel.kind, MaterialKind::Mirror);
                let frame = s.materials.iter().find(|m| m.name == "ChairFrame").unwrap();
                assert_eq!(frame.kind, MaterialKind::Glossy);
                assert!((frame.roughness - 0.316228).abs() < 1e-5);
            }
            "bunny" => {
                assert_eq!(l.environment, Some(Environment::Constant(Vec3::ONE)));
                assert_eq!(s.effects, effects(&["sky"]));
            }
            _ => unreachable!(),
        }
        // Textures exist and decode; sRGB maps decode to the MTL's Kd (= the texture mean).
        for m in &s.materials {
            if let Some(t) = m.albedo_texture
                && m.name.starts_with("sp_00_pod")
            {
                let mean = s.textures[t as usize].mean_rgb();
                assert!((mean - m.albedo).abs().max_element() < 0.01, "{}: {mean} vs Kd {}", m.name, m.albedo);
            }
        }
    }
}

/// The paper's real scenes as the evaluation presets name them: each of the nine manifests
/// in `scenes/` loads, carries a name of its own (no built-in's), stands for a scene of the
/// paper's tables, and has exactly the effect its variant adds over its base scene.
#[test]
fn real_scene_manifests_are_the_papers_variants() {
    let Some(_) = shared_scenes() else { return };
    let paper = stereotrace::eval::paper::PaperTables::load();
    let builtins = builtin::builtin_names();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let load = |stem: &str| {
        resolve(dir.join(format!("{stem}.toml")).to_str().unwrap()).unwrap_or_else(|e| panic!("{stem}: {e}"))
    };
    let mut names = BTreeSet::new();
    for base in ["sponza", "living-room", "classroom"] {
        let b = load(&format!("real-{base}"));
        let variants: &[(&str, Effect)] = match base {
            "classroom" => &[("glossy", Effect::Glossy), ("mirror", Effect::Mirror)],
            _ => &[("glossy", Effect::Glossy), ("moving-light", Effect::MovingLights)],
        };
        for scene in std::iter::once((b.clone(), None))
            .chain(variants.iter().map(|(v, e)| (load(&format!("real-{base}-{v}")), Some(*e))))
        {
            let (s, effect) = scene;
            assert!(!builtins.contains(&s.name.as_str()) && names.insert(s.name.clone()), "{}: name taken", s.name);
            let p = s.paper_scene.as_deref().unwrap_or_else(|| panic!("{}: no paper scene", s.name));
            assert!(paper.scenes().iter().any(|q| q == p), "{}: '{p}' is in none of the paper's tables", s.name);
            assert_eq!(s.triangle_count(), b.triangle_count(), "{}", s.name);
            assert_eq!(s.tolerances, b.tolerances, "{}", s.name);
            if let Some(e) = effect {
                assert!(s.effects.has(e), "{}: lacks {e:?}", s.name);
            }
        }
    }
    // Classroom (Mirror) turns its front board (glossy in the source) into a mirror.
    let board = |s: &Scene| s.materials.iter().find(|m| m.name == "Whiteboard3").unwrap().kind;
    assert_eq!(board(&load("real-classroom-mirror")), MaterialKind::Mirror);
    assert_eq!(board(&load("real-classroom")), MaterialKind::Glossy);
    // Every glossy variant makes all its non-emissive materials glossy (or keeps mirrors).
    let g = load("real-sponza-glossy");
    assert!(g.materials.iter().filter(|m| !m.is_emissive()).all(|m| m.kind != MaterialKind::Diffuse));
}

#[test]
fn example_manifest_expresses_sponza_moving_light() {
    let Some(_) = shared_scenes() else { return };
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/real-sponza-moving-light.toml");
    let s = resolve(path.to_str().unwrap()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(s.name, "real-sponza-moving-light");
    assert_eq!(s.paper_scene.as_deref(), Some("Sponza (Moving Light)"));
    assert_eq!(s.triangle_count(), 67_405);
    assert!(s.effects.has(Effect::MovingLights) && s.effects.has(Effect::AreaLights));
    assert_eq!(s.lights.moving.len(), 1);
    let sphere = s.materials.iter().find(|m| m.name == "arealight_sphere_emitter").unwrap();
    assert!((sphere.emission.x - 4800.0).abs() < 1e-2, "emission scaled by 0.3");
    // The variant keeps its base scene's tolerances, so the two compare on equal terms.
    let base =
        resolve(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/real-sponza.toml").to_str().unwrap()).unwrap();
    assert_eq!(s.tolerances, base.tolerances);
    for f in [0.0, 30.0, 59.0] {
        let PlacedLight::Area { triangles, .. } = s.lights.moving[0].at_frame(f) else { panic!() };
        let c = triangles.iter().flatten().copied().sum::<Vec3>() / (3 * triangles.len()) as f32;
        assert!(mesh_distance(&s.mesh, c, 1.0) > 0.5, "frame {f}: sphere too close to geometry");
    }
}

// ---------------------------------------------------------------------------------------------
// Manifests over a small synthetic mesh

const ROOM_OBJ: &str = "\
mtllib room.mtl
o floor
v -2 0 -2
v 2 0 -2
v 2 0 2
v -2 0 2
vt 0 0
vt 1 0
vt 1 1
vt 0 1
usemtl wall
f 1/1 4/4 3/3 2/2
o board
v -1 0.5 -1.9
v 1 0.5 -1.9
v 1 1.5 -1.9
v -1 1.5 -1.9
usemtl board
f 5 6 7 8
o lamp
v -0.5 1.9 -0.5
v 0.5 1.9 -0.5
v 0.5 1.9 0.5
v -0.5 1.9 0.5
usemtl lamp
f 9 10 11 12
";

const ROOM_MTL: &str = "\
newmtl wall
Kd 0.7 0.7 0.7
illum 1
newmtl board
Kd 0.5
Ks 0.04 0.04 0.04
Pr 0.3
illum 2
newmtl lamp
Kd 0.5 0.5 0.5
Ke 10 10 10
illum 1
";

fn room(dir: &TempDir) -> PathBuf {
    dir.write("room.mtl", ROOM_MTL);
    dir.write(
        "camera.json",
        r#"{"eye": [0, 1, 1.5], "target": [0, 1, -1], "up": [0, 1, 0], "vfov_deg": 50, "width": 64, "height": 36}"#,
    );
    dir.write("room.obj", ROOM_OBJ)
}

#[test]
fn manifests_express_glossy_mirror_and_moving_light_variants() {
    let dir = TempDir::new("manifest");
    room(&dir);
    let base = dir.write("base.toml", "mesh = \"room.obj\"\n");
    let s = load_manifest(&base).unwrap();
    assert_eq!(s.name, "base");
    assert_eq!(s.effects, effects(&["glossy", "area-lights"]), "board is illum 2 with Ks");
    // The lamp's winding faces down, into the room (Ke is one-sided on the winding).
    assert_eq!(s.lights.area.len(), 2);

    let glossy = dir.write("glossy.toml", "mesh = \"room.obj\"\n[materials.all]\nkind = \"glossy\"\nroughness = 0.4\n");
    let s = load_manifest(&glossy).unwrap();
    let wall = s.materials.iter().find(|m| m.name == "wall").unwrap();
    assert_eq!(wall.kind, MaterialKind::Glossy);
    assert!((wall.roughness - 0.4).abs() < 1e-6);
    assert_eq!(
        s.materials.iter().find(|m| m.name == "lamp").unwrap().kind,
        MaterialKind::Diffuse,
        "emitters untouched"
    );

    let mirror = dir.write(
        "mirror.toml",
        "mesh = \"room.obj\"\n[[materials.set]]\nname = \"bo*\"\nkind = \"mirror\"\n[effects]\nglossy = false\n",
    );
    let s = load_manifest(&mirror).unwrap();
    assert_eq!(s.effects, effects(&["mirror", "area-lights"]));

    let moving = dir.write(
        "moving.toml",
        r#"mesh = "room.obj"
frames = 30
[camera]
vfov_deg = 45
keys = [ { frame = 0, eye = [0, 1, 1.5], target = [0, 1, -1] }, { frame = 29, eye = [0.3, 1, 1.4], target = [0, 1, -1] } ]
[[lights]]
type = "moving-point"
intensity = [2, 2, 2]
keys = [ { frame = 0, translation = [-1, 1, 0] }, { frame = 29, translation = [1, 1, 0], yaw_deg = 30 } ]
[[lights]]
type = "sun"
direction = [0.3, 1, 0.2]
irradiance = [3, 3, 3]
[effects]
area_lights = false
textures = true
[tolerances]
position = 0.02
depth_relative = 0.01
normal_degrees = 20
"#,
    );
    let s = load_manifest(&moving).unwrap();
    assert_eq!(s.frame_count(), 30);
    assert_eq!(s.camera.vfov_deg, 45.0);
    assert!(s.lights.area.is_empty(), "area lights stripped");
    assert_eq!(s.effects, effects(&["glossy", "moving-lights", "point-lights", "sun", "textures"]));
    assert_eq!(s.forced_effects, effects(&["textures"]));
    assert_eq!(s.tolerances.normal_degrees, 20.0);
    let PlacedLight::Point(p) = s.lights.moving[0].at_frame(29.0) else { panic!() };
    assert!((p.position - Vec3::new(1.0, 1.0, 0.0)).length() < 1e-5);

    // A moving object with a material of its own; `moving_objects = false` strips it.
    let object = "mesh = \"room.obj\"\n[[objects]]\ntype = \"moving-box\"\nname = \"crate\"\nsize = [0.3, 0.3, 0.3]\nalbedo = [0.6, 0.4, 0.2]\nkind = \"glossy\"\nroughness = 0.2\nkeys = [ { frame = 0, translation = [-0.5, 0.5, -0.5] }, { frame = 59, translation = [0.5, 0.5, -0.5], yaw_deg = 45 } ]\n";
    let s = load_manifest(&dir.write("object.toml", object)).unwrap();
    assert_eq!(s.effects, effects(&["glossy", "area-lights", "moving-objects"]));
    let crate_ = &s.moving_objects[0];
    assert_eq!((crate_.name.as_str(), crate_.triangles.len()), ("crate", 12));
    let m = &s.materials[crate_.material as usize];
    assert_eq!((m.name.as_str(), m.kind, m.roughness), ("object_crate", MaterialKind::Glossy, 0.2));
    let centre = crate_.at_frame(59.0).flatten().sum::<Vec3>() / 36.0;
    assert!((centre - Vec3::new(0.5, 0.5, -0.5)).length() < 1e-5, "{centre}");
    let stripped =
        load_manifest(&dir.write("stripped.toml", format!("{object}[effects]\nmoving_objects = false\n"))).unwrap();
    assert!(stripped.moving_objects.is_empty() && !stripped.effects.has(Effect::MovingObjects));
    let sphere = load_manifest(&dir.write(
        "sphere.toml",
        "mesh = \"room.obj\"\n[[objects]]\ntype = \"moving-sphere\"\nradius = 0.2\nalbedo = [0.5, 0.5, 0.5]\nkeys = [ { frame = 0, translation = [0, 1, -0.5] } ]\n",
    ))
    .unwrap();
    assert_eq!(sphere.moving_objects[0].triangles.len(), 80);
    // Bad objects are refused by key: a zero size, an albedo above 1, an unknown field.
    for (bad, needle) in [
        ("size = [0, 1, 1]", "objects[0]: size"),
        ("size = [1, 1, 1]\nalbedo = [2, 0, 0]", "albedo"),
        ("size = [1, 1, 1]\nalbedo = [0.5, 0.5, 0.5]\nemission = [1, 1, 1]", "emission"),
    ] {
        let body = format!(
            "mesh = \"room.obj\"\n[[objects]]\ntype = \"moving-box\"\n{bad}\nalbedo = [0.5, 0.5, 0.5]\nkeys = [ {{ frame = 0, translation = [0, 1, 0] }} ]\n"
        );
        // A repeated key is itself a TOML error; keep the first albedo only where the case sets one.
        let body =
            if bad.contains("albedo") { body.replacen("\nalbedo = [0.5, 0.5, 0.5]\nkeys", "\nkeys", 1) } else { body };
        let err = load_manifest(&dir.write("bad-object.toml", body)).unwrap_err().to_string();
        assert!(err.contains(needle), "{bad}: {err}");
    }

    // A quad light from a manifest becomes emissive geometry.
    let quad = dir.write(
        "quad.toml",
        "mesh = \"room.obj\"\n[[lights]]\ntype = \"quad\"\ncorners = [[-0.2, 1.95, -0.2], [-0.2, 1.95, 0.2], [0.2, 1.95, 0.2], [0.2, 1.95, -0.2]]\nradiance = [5, 5, 5]\n",
    );
    let s = load_manifest(&quad).unwrap();
    assert_eq!(s.triangle_count(), 8);
    assert_eq!(s.lights.area.len(), 4);
}

#[test]
fn manifest_errors_name_the_file_and_line() {
    let dir = TempDir::new("manifest-errors");
    room(&dir);
    let bad = dir.write("bad.toml", "mesh = \"room.obj\"\nframes = \"sixty\"\n");
    let e = load_manifest(&bad).unwrap_err();
    assert!(matches!(&e, SceneError::Parse { location, .. } if location.line == Some(2)), "{e}");
    assert!(e.to_string().starts_with(&format!("{}:2:", bad.display())), "{e}");

    let syntax = dir.write("syntax.toml", "mesh = \"room.obj\"\n\n[camera\nvfov_deg = 3\n");
    let e = load_manifest(&syntax).unwrap_err();
    assert!(matches!(&e, SceneError::Parse { location, .. } if location.line == Some(3)), "{e}");

    let typo = dir.write("typo.toml", "mesh = \"room.obj\"\nframez = 60\n");
    let e = load_manifest(&typo).unwrap_err();
    assert!(e.to_string().contains("typo.toml:2") && e.to_string().contains("framez"), "{e}");

    let nomatch =
        dir.write("nomatch.toml", "mesh = \"room.obj\"\n[[materials.set]]\nname = \"nothing*\"\nkind = \"mirror\"\n");
    let e = load_manifest(&nomatch).unwrap_err();
    let m = e.to_string();
    assert!(m.contains("nomatch.toml") && m.contains("materials.set[0]") && m.contains("wall"), "{m}");

    let effect = dir.write("effect.toml", "mesh = \"room.obj\"\n[effects]\nshiny = true\n");
    let e = load_manifest(&effect).unwrap_err();
    assert!(e.to_string().contains("effects.shiny"), "{e}");

    let missing = dir.write("missing.toml", "mesh = \"nowhere/scene.obj\"\n");
    let e = load_manifest(&missing).unwrap_err();
    assert!(e.to_string().contains("relative to the manifest"), "{e}");

    let dark = dir.write("dark.toml", "mesh = \"room.obj\"\n[effects]\narea_lights = false\n");
    let e = load_manifest(&dark).unwrap_err();
    assert!(e.to_string().contains("no lights"), "{e}");
}

// ---------------------------------------------------------------------------------------------
// Malformed files

/// Loads `obj` (with `room.mtl` beside it) and returns the error message.
fn obj_error(obj: &str) -> (String, SceneError) {
    let dir = TempDir::new("obj");
    dir.write("room.mtl", ROOM_MTL);
    let p = dir.write("bad.obj", obj);
    let e = load_obj(&p, &ObjOptions::default()).expect_err("should fail");
    (p.display().to_string(), e)
}

#[test]
fn malformed_obj_files_give_file_and_line() {
    // Truncated in the middle of a vertex line.
    let cut = ROOM_OBJ.find("v 2 0 2").unwrap() + 5;
    let (p, e) = obj_error(&ROOM_OBJ[..cut]);
    assert_eq!(e.to_string(), format!("{p}:5: vertex position needs 3 numbers: \"v 2 0\""));

    // Face index out of range.
    let (p, e) = obj_error(&ROOM_OBJ.replace("f 5 6 7 8", "f 5 6 7 80"));
    assert!(e.to_string().starts_with(&format!("{p}:19: vertex index 80 is out of range")), "{e}");
    // Issue 13: "the file defines 12 vertices", not "12 vertexs".
    assert!(e.to_string().ends_with("(the file defines 12 vertices)"), "{e}");
    // Index 0, and relative indices before the first vertex.
    let (p, e) = obj_error(&ROOM_OBJ.replace("f 5 6 7 8", "f 0 6 7"));
    assert!(e.to_string().starts_with(&format!("{p}:19: vertex index 0")), "{e}");
    let (_, e) = obj_error(&ROOM_OBJ.replace("f 5 6 7 8", "f -1 -2 -30"));
    assert!(e.to_string().contains(":19: relative vertex index -30"), "{e}");
    let (_, e) = obj_error(&ROOM_OBJ.replace("f 1/1 4/4 3/3 2/2", "f 1/9 4/4 3/3"));
    assert!(e.to_string().contains(":12: texture coordinate index 9 is out of range"), "{e}");

    // NaN and infinite coordinates.
    let (p, e) = obj_error(&ROOM_OBJ.replace("v 2 0 -2", "v 2 NaN -2"));
    assert_eq!(e.to_string(), format!("{p}:4: vertex position is not finite (NaN or infinity): \"v 2 NaN -2\""));
    let (_, e) = obj_error(&ROOM_OBJ.replace("vt 1 1", "vt 1 inf"));
    assert!(e.to_string().contains(":9: texture coordinate is not finite"), "{e}");
    let (_, e) = obj_error(&ROOM_OBJ.replace("v 2 0 -2", "v 2 0 -2 0"));
    assert!(e.to_string().contains(":4: vertex weight"), "{e}");
    let (_, e) = obj_error(&ROOM_OBJ.replace("v 2 0 -2", "v 2 zero -2"));
    assert!(e.to_string().contains(":4: vertex position needs 3 numbers"), "{e}");

    // Empty mesh.
    let (p, e) = obj_error("# nothing here\nv 0 0 0\n");
    assert!(matches!(e, SceneError::Invalid { .. }));
    assert!(e.to_string().starts_with(&p) && e.to_string().contains("no triangles"), "{e}");
    let (_, e) = obj_error("");
    assert!(e.to_string().contains("no triangles"), "{e}");

    // Missing file, invalid UTF-8, bad statements.
    let e = load_obj(Path::new("/nonexistent/scene.obj"), &ObjOptions::default()).unwrap_err();
    assert!(matches!(e, SceneError::Io { .. }) && e.to_string().contains("/nonexistent/scene.obj"), "{e}");
    let mut bytes = ROOM_OBJ.as_bytes().to_vec();
    bytes.splice(0..0, b"# \xff\xfe\n".iter().copied());
    let dir = TempDir::new("utf8");
    let p = dir.write("bad.obj", &bytes);
    let e = load_obj(&p, &ObjOptions::default()).unwrap_err();
    assert!(e.to_string().contains(":1: not valid UTF-8"), "{e}");
    let (_, e) = obj_error(&ROOM_OBJ.replace("usemtl board", "usemtl"));
    assert!(e.to_string().contains(":18: usemtl without a material name"), "{e}");
}

#[test]
fn missing_and_malformed_mtl_files_are_errors_naming_them() {
    let dir = TempDir::new("mtl");
    let p = dir.write("room.obj", ROOM_OBJ);
    let e = load_obj(&p, &ObjOptions::default()).unwrap_err();
    let m = e.to_string();
    assert!(m.starts_with(&format!("{}:1:", p.display())) && m.contains("room.mtl"), "{m}");

    let mtl = dir.write("room.mtl", ROOM_MTL.replace("Ks 0.04 0.04 0.04", "Ks 0.04 0.04"));
    let e = load_obj(&p, &ObjOptions::default()).unwrap_err();
    assert_eq!(e.to_string(), format!("{}:6: Ks expects 1 or 3 numbers, got 2: \"Ks 0.04 0.04\"", mtl.display()));
    dir.write("room.mtl", ROOM_MTL.replace("illum 2", "illum two"));
    let e = load_obj(&p, &ObjOptions::default()).unwrap_err();
    assert!(e.to_string().contains("room.mtl:8: illum expects an integer"), "{e}");
    dir.write("room.mtl", ROOM_MTL.replace("Ke 10 10 10", "Ke 10 nan 10"));
    let e = load_obj(&p, &ObjOptions::default()).unwrap_err();
    assert!(e.to_string().contains("room.mtl:11: Ke value is not finite"), "{e}");

    // One-value colours are valid MTL (grey) and are expanded, not a tobj panic.
    dir.write("room.mtl", ROOM_MTL);
    let obj = load_obj(&p, &ObjOptions::default()).unwrap();
    let board = obj.materials.iter().find(|m| m.name == "board").unwrap();
    assert_eq!(board.albedo, Vec3::splat(0.5));
    assert_eq!(board.kind, MaterialKind::Glossy);
    assert_eq!(obj.mesh.len(), 6, "three quads");
    assert_eq!(obj.mesh.uvs.as_ref().unwrap()[0][0], Vec2::ZERO);
    assert!(obj.mesh.normals.is_none(), "no vn: flat shaded");
}

#[test]
fn bad_json_gives_line_and_column() {
    let dir = TempDir::new("json");
    room(&dir);
    std::fs::copy(dir.0.join("room.obj"), dir.0.join("scene.obj")).unwrap();
    let cam = dir.write("camera.json", "{\n  \"eye\": [0, 1, 1.5],\n  \"target\": [0, 1, -1]\n  \"vfov_deg\": 50\n}\n");
    let e = load_folder(&dir.0, &FolderOptions::default()).unwrap_err();
    assert!(
        matches!(&e, SceneError::Parse { location, .. } if location.line == Some(4) && location.column.is_some()),
        "{e}"
    );
    assert!(e.to_string().starts_with(&format!("{}:4:", cam.display())), "{e}");

    dir.write("camera.json", r#"{"eye": [0, 1, 1.5], "target": [0, 1, 1.5], "vfov_deg": 50}"#);
    let e = load_folder(&dir.0, &FolderOptions::default()).unwrap_err();
    assert!(e.to_string().contains("camera.json") && e.to_string().contains("eye == target"), "{e}");

    dir.write("camera.json", r#"{"eye": [0, 1, 1.5], "target": [0, 1, -1], "vfov_deg": 50}"#);
    let lights = dir.write("lights.json", "[\n  {\"type\": \"laser\", \"power\": 3}\n]\n");
    let e = load_folder(&dir.0, &FolderOptions::default()).unwrap_err();
    assert!(e.to_string().starts_with(&format!("{}:2:", lights.display())) && e.to_string().contains("laser"), "{e}");

    dir.write(
        "lights.json",
        r#"[{"type": "envmap", "filename": "missing.exr", "to_world": [[1,0,0],[0,1,0],[0,0,1]]}]"#,
    );
    let e = load_folder(&dir.0, &FolderOptions::default()).unwrap_err();
    assert!(e.to_string().contains("missing.exr"), "{e}");

    // Issue 13: a null where a string belongs is refused naming the light and the field
    // (serde alone names neither), and the position is printed once.
    dir.write(
        "lights.json",
        "[\n  {\"type\": \"constant\", \"radiance\": [1, 1, 1]},\n  {\"type\": \"envmap\", \"filename\": null, \
         \"to_world\": [[1,0,0],[0,1,0],[0,0,1]]}\n]\n",
    );
    let e = load_folder(&dir.0, &FolderOptions::default()).unwrap_err().to_string();
    // A Mitsuba scene converted without its environment image: the message says what is
    // missing and what to do, not serde's type error.
    assert!(e.contains("light 1: an \"envmap\" light has no image (\"filename\" is null"), "{e}");
    assert!(e.contains("drop this entry") && !e.contains("invalid type"), "{e}");
    assert!(!e.contains("at line"), "position printed twice: {e}");
    dir.write("lights.json", "[\n  {\"type\": \"point\", \"position\": null, \"intensity\": [1, 1, 1]}\n]\n");
    let e = load_folder(&dir.0, &FolderOptions::default()).unwrap_err().to_string();
    assert!(
        e.contains("light 0 (type \"point\"), field \"position\" is null, but an array of length 3 is required"),
        "{e}"
    );
    dir.write("lights.json", "[]");
    dir.write("camera.json", r#"{"eye": [0, 1, 1.5], "target": [0, 1, -1], "vfov_deg": null}"#);
    let e = load_folder(&dir.0, &FolderOptions::default()).unwrap_err().to_string();
    assert!(e.contains("camera.json:1:") && e.contains("field \"vfov_deg\" is null, but f32 is required"), "{e}");
    dir.write("camera.json", r#"{"eye": [0, 1, 1.5], "target": [0, 1, -1], "vfov_deg": "wide"}"#);
    let e = load_folder(&dir.0, &FolderOptions::default()).unwrap_err().to_string();
    assert!(e.contains("camera.json:1:") && e.contains("expected f32") && !e.contains("at line"), "{e}");
    dir.write("camera.json", r#"{"eye": [0, 1, 1.5], "target": [0, 1, -1], "vfov_deg": 50}"#);
    // Issue 13: a sun without power names its irradiance, not a struct dump.
    dir.write("lights.json", r#"[{"type": "sun", "direction": [0, 1, 0], "irradiance": [0, 0, 0]}]"#);
    let e = load_folder(&dir.0, &FolderOptions::default()).unwrap_err().to_string();
    assert!(e.contains("sun irradiance [0, 0, 0]") && !e.contains("SunLight {"), "{e}");

    dir.write("lights.json", r#"[{"type": "constant", "radiance": [0.5, 0.5, 0.5]}]"#);
    let s = load_folder(&dir.0, &FolderOptions::default()).unwrap();
    assert!(s.effects.has(Effect::Sky) && s.effects.has(Effect::AreaLights));

    std::fs::remove_file(dir.0.join("camera.json")).unwrap();
    let e = load_folder(&dir.0, &FolderOptions::default()).unwrap_err();
    assert!(e.to_string().contains("camera.json"), "{e}");
}

#[test]
fn missing_textures_warn_and_keep_the_flat_colour() {
    let dir = TempDir::new("texture");
    room(&dir);
    dir.write("room.mtl", ROOM_MTL.replace("Kd 0.7 0.7 0.7", "Kd 0.7 0.7 0.7\nmap_Kd nothing.png\nmap_d nomask.png"));
    let obj = load_obj(&dir.0.join("room.obj"), &ObjOptions::default()).unwrap();
    let wall = obj.materials.iter().find(|m| m.name == "wall").unwrap();
    assert!(wall.albedo_texture.is_none() && wall.opacity_texture.is_none());
    assert_eq!(wall.albedo, Vec3::splat(0.7));
    assert_eq!(obj.warnings.len(), 2, "{:?}", obj.warnings);
    assert!(obj.warnings[0].contains("nothing.png") && obj.warnings[0].contains("flat Kd"), "{:?}", obj.warnings);

    // A file that is not an image warns the same way.
    dir.write("nothing.png", "not a png");
    let obj = load_obj(&dir.0.join("room.obj"), &ObjOptions::default()).unwrap();
    assert!(
        obj.warnings.iter().any(|w| w.contains("nothing.png") && w.contains("cannot decode")),
        "{:?}",
        obj.warnings
    );
}

#[test]
fn tobj_never_panics_on_garbage() {
    // A fixed-seed fuzz over OBJ-like lines: every input loads or errors, nothing panics.
    let dir = TempDir::new("fuzz");
    dir.write("room.mtl", ROOM_MTL);
    let tokens = [
        "v", "vt", "vn", "f", "o", "g", "usemtl", "mtllib", "s", "l", "1", "-1", "2/3", "1//2", "0", "-7", "1.5",
        "nan", "1e40", "wall", "board", "room.mtl", "/", "//", "#", "3/", "4/4/4/4",
    ];
    let mut rng = stereotrace_kernels::synth::Rng::new(0x1234_5678_9abc_def0);
    let mut next = || rng.next_u64();
    for case in 0..300 {
        let mut text = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n");
        for _ in 0..(next() % 12) {
            let n = next() % 6;
            let line: Vec<&str> = (0..n).map(|_| tokens[(next() % tokens.len() as u64) as usize]).collect();
            text.push_str(&line.join(" "));
            text.push('\n');
        }
        let p = dir.write(&format!("f{case}.obj"), &text);
        let r = std::panic::catch_unwind(|| load_obj(&p, &ObjOptions::default()).map(|d| d.mesh.len()));
        assert!(r.is_ok(), "panic on:\n{text}");
        if let Ok(Ok(_)) = r {
            let d = load_obj(&p, &ObjOptions::default()).unwrap();
            d.mesh.validate(d.materials.len()).unwrap();
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Textures

/// A 531-byte JPEG on which zune-jpeg 0.5.15 panics in its AVX2 IDCT (an out-of-range
/// block slice is unwrapped; found by fuzzing, `fuzz/corpus/image`, whose first byte is the
/// target's format selector). Loading it must give an image error, for both uses, instead
/// of unwinding into the scene loader.
#[test]
fn a_jpeg_that_panics_the_decoder_gives_an_image_error() {
    let input = include_bytes!("../fuzz/corpus/image/1e9caa97027758c204a5a31e7722e4d3da2a82cf");
    let dir = TempDir::new("panicking-jpeg");
    let p = dir.0.join("corrupt.jpg");
    std::fs::write(&p, &input[1..]).unwrap();
    for usage in [TextureUsage::Albedo, TextureUsage::Mask] {
        let e = Texture::load(&p, usage).unwrap_err();
        assert!(matches!(e, SceneError::Image { .. }), "{e:?}");
        assert!(e.to_string().contains("corrupt.jpg") && e.to_string().contains("the decoder failed"), "{e}");
    }
}

/// A grey JPEG whose header claims 20036×18757 texels (the file stays a few hundred bytes)
/// took gigabytes to decode and convert to f32 (found by fuzzing, `fuzz/corpus/image`); it
/// is now refused from its header, for both uses.
#[test]
fn a_texture_claiming_too_many_texels_is_refused_before_decoding() {
    let dir = TempDir::new("huge-jpeg");
    let mut bytes = Vec::new();
    image::GrayImage::new(8, 8).write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Jpeg).unwrap();
    let sof = bytes.windows(2).position(|w| w == [0xFF, 0xC0]).expect("a baseline JPEG");
    // After the marker: length (2 bytes), precision (1), height (2), width (2).
    bytes[sof + 5..sof + 9].copy_from_slice(&[0x49, 0x45, 0x4E, 0x44]);
    let p = dir.0.join("huge.jpg");
    std::fs::write(&p, &bytes).unwrap();
    for usage in [TextureUsage::Albedo, TextureUsage::Mask] {
        let e = Texture::load(&p, usage).unwrap_err().to_string();
        assert!(e.contains("huge.jpg") && e.contains("20036x18757") && e.contains("refused before decoding"), "{e}");
    }
}

#[test]
fn textures_decode_srgb_and_put_v_zero_at_the_bottom() {
    let dir = TempDir::new("png");
    // 2x2 RGBA: top row (188,0,0,255) (0,188,0,255); bottom row (0,0,188,64) (255,255,255,0).
    let img = image::RgbaImage::from_raw(2, 2, vec![188, 0, 0, 255, 0, 188, 0, 255, 0, 0, 188, 64, 255, 255, 255, 0])
        .unwrap();
    let p = dir.0.join("t.png");
    img.save(&p).unwrap();
    let t = Texture::load(&p, TextureUsage::Albedo).unwrap();
    assert_eq!((t.width, t.height, t.channels), (2, 2, 4));
    let lin = srgb_to_linear(188.0 / 255.0);
    assert!((lin - 0.5029).abs() < 1e-3);
    let bl = t.sample(Vec2::new(0.25, 0.25));
    assert!((bl.z - lin).abs() < 1e-6 && bl.x == 0.0, "bottom-left is the blue texel: {bl}");
    assert!((bl.w - 64.0 / 255.0).abs() < 1e-6, "alpha is linear");
    let tl = t.sample(Vec2::new(0.25, 0.75));
    assert!((tl.x - lin).abs() < 1e-6, "top-left is the red texel: {tl}");
    let mask = Texture::load(&p, TextureUsage::Mask).unwrap();
    assert_eq!(mask.channels, 1);
    assert!((mask.sample(Vec2::new(0.75, 0.25)).x - 0.0).abs() < 1e-6);
    assert!((mask.sample(Vec2::new(0.75, 0.75)).x - 1.0).abs() < 1e-6);

    // Through an MTL: map_Kd and map_d on the same file; coverage follows the alpha channel.
    room(&dir);
    dir.write("room.mtl", ROOM_MTL.replace("Kd 0.7 0.7 0.7", "Kd 0.7 0.7 0.7\nmap_Kd t.png\nmap_d t.png"));
    let obj = load_obj(&dir.0.join("room.obj"), &ObjOptions::default()).unwrap();
    let wall = obj.materials.iter().find(|m| m.name == "wall").unwrap();
    let (a, c) = (wall.albedo_texture.unwrap(), wall.opacity_texture.unwrap());
    assert_ne!(a, c);
    assert!((wall.albedo_at(&obj.textures, Vec2::new(0.25, 0.75)).x - lin).abs() < 1e-6);
    assert_eq!(wall.coverage_at(&obj.textures, Vec2::new(0.75, 0.25)), 0.0);
    assert!(wall.has_cutout());
}

// ---------------------------------------------------------------------------------------------
// Environment maps

fn synthetic_envmap() -> EnvMap {
    let (w, h) = (32u32, 16u32);
    let mut data = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let (u, v) = ((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
            let sky = 0.3 + 0.7 * (1.0 - v) + 0.3 * (6.0 * u).sin().abs();
            let sun = if (x, y) == (9, 4) || (x, y) == (10, 4) { 30.0 } else { 0.0 };
            data.extend([sky + sun, sky * 0.9 + sun, sky * 0.8 + sun * 0.5]);
        }
    }
    let tex = Texture::new("synthetic", w, h, 3, data).unwrap();
    // The living room's to_world (90° about +Y) composed with a tilt, to exercise the mapping.
    let to_world = Mat3::from_rotation_x(0.3) * Mat3::from_rotation_y(std::f32::consts::FRAC_PI_2);
    EnvMap::new(tex, 1.5, to_world).unwrap()
}

/// ∫ pdf dω over the sphere, by the midpoint rule over (u, v) (dω = 2π² sin θ du dv).
fn integrate_pdf(map: &EnvMap, nu: usize, nv: usize) -> f64 {
    let mut sum = 0.0f64;
    for j in 0..nv {
        let v = (j as f32 + 0.5) / nv as f32;
        let w = 2.0 * std::f64::consts::PI.powi(2) * (std::f64::consts::PI * v as f64).sin() / (nu * nv) as f64;
        for i in 0..nu {
            let u = (i as f32 + 0.5) / nu as f32;
            sum += map.pdf(map.uv_to_direction(Vec2::new(u, v))) as f64 * w;
        }
    }
    sum
}

#[test]
fn envmap_pdf_integrates_to_one() {
    let map = synthetic_envmap();
    let grid = integrate_pdf(&map, 512, 256);
    assert!((grid - 1.0).abs() < 2e-3, "grid integral {grid}");
    // Independently: E[pdf / (1 / 4π)] over uniform directions is 1.
    let n = 400_000;
    let mut sum = 0.0f64;
    for i in 0..n {
        let u = Vec2::new((i as f32 + 0.5) / n as f32, (i as f32 * 0.618_034).fract());
        sum += map.pdf(uniform_sphere(u)) as f64 * 4.0 * std::f64::consts::PI;
    }
    let mc = sum / n as f64;
    assert!((mc - 1.0).abs() < 0.02, "Monte Carlo integral {mc}");
}

#[test]
fn envmap_samples_follow_the_pdf_chi_square() {
    let map = synthetic_envmap();
    // Equal-area bins in world (cos θ, φ).
    let (nt, np) = (10usize, 20usize);
    let bin = |d: Vec3| {
        let t = (((d.y + 1.0) * 0.5 * nt as f32) as usize).min(nt - 1);
        let mut phi = d.z.atan2(d.x);
        if phi < 0.0 {
            phi += std::f32::consts::TAU;
        }
        let p = ((phi / std::f32::consts::TAU * np as f32) as usize).min(np - 1);
        t * np + p
    };
    // Expected probability per bin: the pdf integrated over the bin (64 x 64 midpoints).
    let sub = 64;
    let area = 4.0 * std::f64::consts::PI / (nt * np) as f64;
    let mut expected = vec![0.0f64; nt * np];
    for (k, e) in expected.iter_mut().enumerate() {
        let (t, p) = (k / np, k % np);
        let mut s = 0.0f64;
        for a in 0..sub {
            for b in 0..sub {
                let z = -1.0 + 2.0 * (t as f32 + (a as f32 + 0.5) / sub as f32) / nt as f32;
                let phi = std::f32::consts::TAU * (p as f32 + (b as f32 + 0.5) / sub as f32) / np as f32;
                let r = (1.0 - z * z).max(0.0).sqrt();
                s += map.pdf(Vec3::new(r * phi.cos(), z, r * phi.sin())) as f64;
            }
        }
        *e = s / (sub * sub) as f64 * area;
    }
    let total: f64 = expected.iter().sum();
    assert!((total - 1.0).abs() < 3e-3, "{total}");

    let n = 200_000usize;
    let mut observed = vec![0usize; nt * np];
    let mut state = 0x853c_49e6_748f_ea9bu64;
    let mut rnd = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((state >> 40) as f32) / (1u64 << 24) as f32
    };
    for _ in 0..n {
        let s = map.sample(Vec2::new(rnd(), rnd()));
        assert!(s.pdf > 0.0 && s.direction.is_finite());
        observed[bin(s.direction)] += 1;
    }
    // Pool bins with fewer than 5 expected samples.
    let (mut chi2, mut dof, mut pool_o, mut pool_e) = (0.0f64, 0usize, 0.0f64, 0.0f64);
    for (o, e) in observed.iter().zip(&expected) {
        let e = e * n as f64;
        if e < 5.0 {
            pool_o += *o as f64;
            pool_e += e;
        } else {
            chi2 += (*o as f64 - e).powi(2) / e;
            dof += 1;
        }
    }
    if pool_e > 0.0 {
        chi2 += (pool_o - pool_e).powi(2) / pool_e.max(1.0);
        dof += 1;
    }
    let k = (dof - 1) as f64;
    // Wilson–Hilferty: the chi-square quantile at 1 − 1e-4 (z = 3.719).
    let critical = k * (1.0 - 2.0 / (9.0 * k) + 3.719 * (2.0 / (9.0 * k)).sqrt()).powi(3);
    assert!(chi2 < critical, "chi2 {chi2:.1} >= {critical:.1} with {k} dof");
}

#[test]
fn sky_19_pdf_integrates_to_one_and_samples_are_consistent() {
    let Some(root) = shared_scenes() else { return };
    let s = load_folder(&root.join("living-room"), &FolderOptions::default()).unwrap();
    let Some(Environment::Map(map)) = &s.lights.environment else { panic!() };
    let grid = integrate_pdf(map, 4096, 2048);
    assert!((grid - 1.0).abs() < 2e-3, "{grid}");
    let mut state = 7u64;
    for _ in 0..20_000 {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        let u = Vec2::new(
            ((state >> 40) as f32) / (1u64 << 24) as f32,
            ((state >> 16 & 0xff_ffff) as f32) / (1u64 << 24) as f32,
        );
        let smp = map.sample(u);
        let p = map.pdf(smp.direction);
        assert!(smp.pdf > 0.0 && (p - smp.pdf).abs() <= 5e-3 * smp.pdf, "{p} vs {}", smp.pdf);
        assert!(smp.radiance.max_element() > 0.0, "sampled a black texel");
    }
}

/// A scene folder holding the room: scene.obj + room.mtl + camera.json (+ `source_md`).
fn room_folder(dir: &TempDir, camera: &str, source_md: Option<&str>) {
    room(dir);
    std::fs::copy(dir.0.join("room.obj"), dir.0.join("scene.obj")).unwrap();
    dir.write("camera.json", camera);
    if let Some(text) = source_md {
        dir.write("SOURCE.md", text);
    }
}

const ROOM_CAMERA: &str = r#"{"eye": [0, 1, 1.5], "target": [0, 1, -1], "vfov_deg": 50"#;

#[test]
fn scene_units_come_from_camera_json_then_source_md_then_a_warning() {
    let bounds = |s: &Scene| s.bounds().extent();
    let reference = {
        let dir = TempDir::new("units-m");
        room_folder(&dir, &format!("{ROOM_CAMERA}, \"meters_per_unit\": 1.0}}"), None);
        load_folder(&dir.0, &FolderOptions::default()).unwrap()
    };
    assert_eq!(reference.units, Units { meters_per_unit: 1.0, from: UnitsFrom::CameraJson });
    assert!(reference.warnings.iter().all(|w| !w.contains("unit")), "{:?}", reference.warnings);

    // camera.json wins over SOURCE.md (and their disagreement is reported).
    let dir = TempDir::new("units-mm");
    room_folder(&dir, &format!("{ROOM_CAMERA}, \"meters_per_unit\": 0.001}}"), Some("- Units: Centimetres\n"));
    let mm = load_folder(&dir.0, &FolderOptions::default()).unwrap();
    assert_eq!(mm.units.from, UnitsFrom::CameraJson);
    assert!((bounds(&mm) - bounds(&reference) * 0.001).abs().max_element() < 1e-6);
    assert!(mm.warnings.iter().any(|w| w.contains("SOURCE.md") && w.contains("0.01")), "{:?}", mm.warnings);

    // Without meters_per_unit: SOURCE.md's Units line, feet included (they used to load as metres).
    let dir = TempDir::new("units-ft");
    room_folder(&dir, &format!("{ROOM_CAMERA}}}"), Some("- Units: feet (the source's)\n"));
    let ft = load_folder(&dir.0, &FolderOptions::default()).unwrap();
    assert_eq!(ft.units, Units { meters_per_unit: 0.3048, from: UnitsFrom::SourceMd });

    // Neither: metres, with a warning that says so.
    let dir = TempDir::new("units-none");
    room_folder(&dir, &format!("{ROOM_CAMERA}}}"), Some("- Units: cubits, probably\n"));
    let unknown = load_folder(&dir.0, &FolderOptions::default()).unwrap();
    assert_eq!(unknown.units.from, UnitsFrom::Assumed);
    assert!(unknown.warnings.iter().any(|w| w.contains("unit is unknown")), "{:?}", unknown.warnings);

    // A manifest's meters_per_unit (or its older name scale, not both).
    let m = dir.write("m.toml", "mesh = \"scene.obj\"\nmeters_per_unit = 0.01\n");
    let cm = load_manifest(&m).unwrap();
    assert_eq!(cm.units, Units { meters_per_unit: 0.01, from: UnitsFrom::Manifest });
    let both = dir.write("both.toml", "mesh = \"scene.obj\"\nmeters_per_unit = 0.01\nscale = 0.01\n");
    assert!(load_manifest(&both).unwrap_err().to_string().contains("meters_per_unit"));
}

#[test]
fn camera_json_fields_are_validated_by_name() {
    for (camera, needle) in [
        (r#"{"eye": [0, 1, 1.5], "target": [0, 1, -1], "up": [0, 0, 0], "vfov_deg": 50}"#, "up"),
        (r#"{"eye": [0, 1, 1.5], "target": [0, 1, -1], "up": [0, 0, 2], "vfov_deg": 50}"#, "parallel"),
        (r#"{"eye": [0, 1, 1.5], "target": [0, 1, -1], "vfov_deg": 1e-30}"#, "vfov_deg"),
        (r#"{"eye": [0, 1, 1.5], "target": [0, 1, -1], "vfov_deg": 50, "meters_per_unit": -1}"#, "meters_per_unit"),
    ] {
        let dir = TempDir::new("camera-fields");
        room_folder(&dir, camera, None);
        let e = load_folder(&dir.0, &FolderOptions::default()).unwrap_err().to_string();
        assert!(e.contains("camera.json") && e.contains(needle), "{camera}: {e}");
    }
}

#[test]
fn lights_too_bright_for_f32_are_refused_naming_the_light() {
    // Ke 3e38 used to be dropped (its power overflowed) and the scene refused as having no
    // lights; 5e37 rendered inf pixels at 16 spp.
    for ke in ["3e38 3e38 3e38", "5e37 5e37 5e37", "2e15 0 0"] {
        let dir = TempDir::new("bright");
        room_folder(&dir, &format!("{ROOM_CAMERA}}}"), None);
        dir.write("room.mtl", ROOM_MTL.replace("Ke 10 10 10", &format!("Ke {ke}")));
        let e = load_folder(&dir.0, &FolderOptions::default()).unwrap_err().to_string();
        assert!(e.contains("\"lamp\"") && e.contains("Ke") && e.contains("exceeds"), "Ke {ke}: {e}");
    }
    // A point light of 2.7e37 used to give inf/inf selection probabilities and a black image.
    let dir = TempDir::new("bright-point");
    room_folder(&dir, &format!("{ROOM_CAMERA}}}"), None);
    dir.write("lights.json", r#"[{"type": "point", "position": [0, 1.5, 0], "intensity": [2.7e37, 2.7e37, 2.7e37]}]"#);
    let e = load_folder(&dir.0, &FolderOptions::default()).unwrap_err().to_string();
    assert!(e.contains("point light") && e.contains("intensity") && e.contains("exceeds"), "{e}");
    // Just below the ceiling works and renders finite values (tests/correct_images.rs and
    // tests/render.rs check the images themselves).
    dir.write("lights.json", r#"[{"type": "point", "position": [0, 1.5, 0], "intensity": [1e15, 1e15, 1e15]}]"#);
    assert!(load_folder(&dir.0, &FolderOptions::default()).is_ok());
}

mod common;

/// Hostile counts and sizes are refused with the bound in the message, before anything the
/// size of the claim is allocated (each used to abort the process allocating gigabytes).
#[test]
fn huge_claims_in_scene_inputs_are_refused_before_allocating() {
    let dir = TempDir::new("huge-claims");
    room(&dir);
    // 4·10⁹ frames: the camera path would have built every pose (208 GB).
    let m = dir.write("frames.toml", "mesh = \"room.obj\"\nframes = 4000000000\n");
    let e = load_manifest(&m).unwrap_err().to_string();
    assert!(e.contains("frames.toml") && e.contains("frames") && e.contains("100000"), "{e}");
    // frames = 0 is the manifest's field, not camera.json's.
    let m = dir.write("zero.toml", "mesh = \"room.obj\"\nframes = 0\n");
    let e = load_manifest(&m).unwrap_err().to_string();
    assert!(e.contains("zero.toml") && e.contains("frames") && !e.contains("camera.json"), "{e}");
    // A field of view of 1e-30 degrees is refused at load, naming the manifest and the camera.
    let m = dir.write(
        "vfov.toml",
        "mesh = \"room.obj\"\n[camera]\nvfov_deg = 1e-30\nkeys = [ { frame = 0, eye = [0, 1, 1.5], target = [0, 1, -1] } ]\n",
    );
    let e = load_manifest(&m).unwrap_err().to_string();
    assert!(e.contains("vfov.toml") && e.contains("camera") && e.contains("field of view"), "{e}");
    // An environment map whose 28-byte-window header claims 65536×65536 pixels (51 GB).
    let exr = dir.0.join("huge.exr");
    common::exr_claiming(&exr, 65536);
    let e = EnvMap::load_exr(&exr, 1.0, Mat3::IDENTITY).unwrap_err().to_string();
    assert!(e.contains("huge.exr") && e.contains("too large"), "{e}");
}
