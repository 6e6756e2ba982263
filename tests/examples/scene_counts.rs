//! Traversal work per ray in a scene's flat tree (the one the path tracer
//! queries): 8-wide nodes and triangle packs tested per closest-hit and
//! any-hit query, for rays from random points inside the scene's bounds in
//! random directions (as diffuse bounces go), any-hit rays stopping just
//! short of the closest hit (as shadow rays do). A diagnostic of tree quality
//! and the fixed workload for instruction counts of the traversal core under
//! valgrind.
//!
//! ```text
//! cargo run --release -p lucent-tests --example scene_counts -- res/scenes/cornell-mitsuba.toml [RAYS]
//! ```
#![allow(clippy::print_stdout, reason = "a measuring tool reports on stdout")]

use lucent_accel::TraversalCounts;
use lucent_geom::{Pcg32, Ray, Vec3};
use std::path::Path;
use std::process::ExitCode;

fn run(args: &[String]) -> Result<(), String> {
    let [path, rest @ ..] = args else {
        return Err("usage: scene_counts SCENE [RAYS]".to_owned());
    };
    let n: u32 = match rest.first() {
        Some(s) => s.parse().map_err(|e| format!("RAYS {s}: {e}"))?,
        None => 200_000,
    };
    let (scene, _) = lucent_assets::load_scene(Path::new(path)).map_err(|e| e.to_string())?;
    let render = lucent_render::extract(&scene).map_err(|e| e.to_string())?;
    let flat = render.flat_bvh().ok_or("the scene has no flat tree")?.mesh_bvh();
    let b = flat.bounds();
    let mut rng = Pcg32::new(1, 1);
    let (mut closest, mut any, mut hits) = (TraversalCounts::default(), TraversalCounts::default(), 0u32);
    for _ in 0..n {
        let mut r = || rng.next_f32();
        let inside = Vec3::new(0.05 + 0.9 * r(), 0.05 + 0.9 * r(), 0.05 + 0.9 * r());
        let origin = b.min + (b.max - b.min) * inside;
        let dir = Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5);
        let ray = Ray::new(origin, dir);
        if let Some(h) = flat.intersect_counted(&ray, f32::INFINITY, &mut closest) {
            hits += 1;
            flat.occluded_counted(&ray, h.t * 0.999, &mut any);
        }
    }
    let ([cn, cp], [an, ap]) = (closest.per_ray(), any.per_ray());
    println!(
        "{{\"triangles\":{},\"wide_nodes\":{},\"rays\":{n},\"hits\":{hits},\
         \"closest_nodes_per_ray\":{cn:.3},\"closest_packs_per_ray\":{cp:.3},\
         \"any_nodes_per_ray\":{an:.3},\"any_packs_per_ray\":{ap:.3}}}",
        flat.n_triangles(),
        flat.n_wide_nodes()
    );
    Ok(())
}

fn main() -> ExitCode {
    lucent_tests::example_main(run)
}
