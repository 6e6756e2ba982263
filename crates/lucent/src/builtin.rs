//! The built-in seed scene, compiled into the binary so the viewer opens it
//! from any working directory (and after `cargo install`).

use lucent_assets::MemorySource;

/// Path of the built-in scene inside [`source`].
pub const SEED_SCENE: &str = "res/scenes/seed.toml";

/// The seed scene and every file it refers to, as an in-memory asset source.
pub fn source() -> MemorySource {
    MemorySource::new()
        .with_file(SEED_SCENE, include_bytes!("../../../res/scenes/seed.toml"))
        .with_file(
            "res/meshes/spot/cow.obj",
            include_bytes!("../../../res/meshes/spot/cow.obj"),
        )
        .with_file(
            "res/meshes/spot/cow.mtl",
            include_bytes!("../../../res/meshes/spot/cow.mtl"),
        )
        .with_file(
            "res/meshes/spot/cow_texture.png",
            include_bytes!("../../../res/meshes/spot/cow_texture.png"),
        )
        .with_file(
            "res/meshes/bunny/bun_zipper.ply",
            include_bytes!("../../../res/meshes/bunny/bun_zipper.ply"),
        )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_scene_loads_everything_it_names() {
        let loaded = lucent_assets::load_scene_from(&source(), std::path::Path::new(SEED_SCENE));
        let (scene, _report) = loaded.unwrap_or_else(|e| panic!("{e}"));
        let c = scene.counts();
        assert_eq!((c.instances, c.lights, c.cameras), (4, 1, 1));
    }
}
