//! Image and statistics snapshots of the seed scene with both shading modes,
//! and a text snapshot of what the seed scene loads into.

use lucent_render::{Film, Shading, extract};
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
