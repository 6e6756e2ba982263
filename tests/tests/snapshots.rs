//! Image and statistics snapshots of the seed scene with both integrators
//! (Whitted in both shading modes, and the path tracer), of the Mitsuba
//! Cornell box with the path tracer, and a text snapshot of what the seed
//! scene loads into.

use lucent_render::{Film, Integrator, Shading, Tonemap, extract};
use lucent_tests::{assert_image_snapshot, load_repo_scene, render_scene};

/// The seed scene at 128x72, 2 samples per pixel, seed 1.
fn seed_film(shading: Shading) -> Film {
    let scene = load_repo_scene("res/scenes/seed.toml");
    render_scene(&scene, |s| {
        (s.width, s.height, s.spp, s.seed, s.shading) = (128, 72, 2, 1, shading);
    })
}

#[test]
fn seed_scene_gouraud() {
    assert_image_snapshot!("seed_gouraud", &seed_film(Shading::Gouraud));
}

#[test]
fn seed_scene_phong() {
    assert_image_snapshot!("seed_phong", &seed_film(Shading::Phong));
}

/// The seed scene path traced at 128x72, 8 samples per pixel, max depth 8,
/// seed 1: the report's scene moved to physically based materials (its
/// directional light and background light it).
#[test]
fn seed_scene_path() {
    let scene = load_repo_scene("res/scenes/seed.toml");
    let film = render_scene(&scene, |s| {
        (s.width, s.height, s.spp, s.seed) = (128, 72, 8, 1);
        (s.integrator, s.max_depth) = (Integrator::Path, 8);
    });
    assert_image_snapshot!("seed_path", &film);
}

/// The Mitsuba Cornell box at 64x64, 16 samples per pixel, max depth 16
/// (its own settings otherwise).
#[test]
fn cornell_mitsuba_path() {
    let scene = load_repo_scene("res/scenes/cornell-mitsuba.toml");
    let film = render_scene(&scene, |s| {
        (s.width, s.height, s.spp, s.seed) = (64, 64, 16, 1);
    });
    assert_image_snapshot!("cornell_mitsuba_path", &film);
}

/// The glTF scene `res/scenes/pbr-shelf.gltf` (instanced metallic-roughness
/// cubes, a transformed and mirrored checker texture, a normal map with
/// MikkTSpace tangents, a double-sided emissive panel, a spot light, the
/// file's camera) path traced at 96x64, 8 samples per pixel, seed 1.
#[test]
fn gltf_pbr_shelf_path() {
    let scene = load_repo_scene("res/scenes/pbr-shelf.gltf");
    let film = render_scene(&scene, |s| {
        (s.width, s.height, s.spp, s.seed) = (96, 64, 8, 1);
    });
    assert_image_snapshot!("gltf_pbr_shelf_path", &film);
}

/// The environment-map scene (Royal Esplanade, a diffuse, a rough and a
/// mirror sphere) at 64x48, 16 samples per pixel, seed 1, through the
/// filmic tone curve it asks for: the sun's highlights roll off instead of
/// clipping.
#[test]
fn envmap_filmic() {
    let scene = load_repo_scene("res/scenes/envmap-mitsuba.toml");
    assert_eq!(scene.settings.tonemap, Tonemap::Filmic);
    let film = render_scene(&scene, |s| {
        (s.width, s.height, s.spp, s.seed) = (64, 48, 16, 1);
    });
    assert_image_snapshot!("envmap_filmic", &film, Tonemap::Filmic);
}

#[test]
fn seed_scene_contents() {
    let scene = load_repo_scene("res/scenes/seed.toml");
    let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
    let mut out = String::new();
    let c = scene.counts();
    out += &format!(
        "entities: {} meshes, {} materials, {} instances, {} lights, {} cameras\n",
        c.meshes, c.materials, c.instances, c.lights, c.cameras
    );
    out += &format!("features: {:?}\n", rs.features);
    for (i, inst) in rs.instances.iter().enumerate() {
        let mesh = &rs.meshes[inst.mesh as usize];
        let bvh = rs.bvh.meshes()[inst.mesh as usize].stats();
        let attrs = [
            ("normals", mesh.normals().is_some()),
            ("uvs", mesh.uvs().is_some()),
            ("colors", mesh.colors().is_some()),
        ];
        let attrs: Vec<&str> = attrs.iter().filter(|a| a.1).map(|a| a.0).collect();
        out += &format!(
            "{}: {} vertices, {} triangles, attributes [{}], bvh {} nodes, {} leaves, depth {}, max leaf {}, sah {:.2}\n",
            rs.instance_names[i],
            mesh.n_vertices(),
            mesh.n_triangles(),
            attrs.join(", "),
            bvh.n_nodes,
            bvh.n_leaves,
            bvh.max_depth,
            bvh.max_leaf_size,
            bvh.sah_cost,
        );
    }
    insta::assert_snapshot!(out);
}
