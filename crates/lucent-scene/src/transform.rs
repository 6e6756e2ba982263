//! World transforms: `Transform` composed along `Parent` links.
//!
//! There is deliberately no cached global-transform component: a cache
//! would go stale whenever a `Transform` changed without a system re-run,
//! and the one consumer (the render extract) walks the chain once per
//! instance anyway.

use crate::components::{Parent, Transform};
use hecs::{Entity, World};
use lucent_geom::Affine3A;

/// Longest parent chain followed; deeper chains (or cycles) stop here.
const MAX_HIERARCHY_DEPTH: usize = 64;

/// The world-from-object transform of `entity`: its [`Transform`] composed
/// with its parents' (`parent * child`). A parent without a transform ends
/// the chain; chains are followed at most 64 levels, so cycles terminate.
/// Identity for an entity without a transform.
pub fn world_from_local(world: &World, entity: Entity) -> Affine3A {
    let mut m = Affine3A::IDENTITY;
    let mut current = Some(entity);
    for _ in 0..MAX_HIERARCHY_DEPTH {
        let Some(e) = current else { break };
        match world.get::<&Transform>(e) {
            Ok(t) => m = t.0 * m,
            Err(_) => break,
        }
        current = world.get::<&Parent>(e).ok().map(|p| p.0);
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_geom::Vec3;

    #[test]
    fn children_follow_parents_and_cycles_terminate() {
        let mut world = World::new();
        let root = world.spawn((Transform(Affine3A::from_translation(Vec3::X)),));
        let child = world.spawn((Transform(Affine3A::from_scale(Vec3::splat(2.0))), Parent(root)));
        let orphan = world.spawn((Transform(Affine3A::from_translation(Vec3::Y)),));
        let p = world_from_local(&world, child).transform_point3(Vec3::ONE);
        assert_eq!(p, Vec3::new(3.0, 2.0, 2.0));
        assert_eq!(world_from_local(&world, orphan), Affine3A::from_translation(Vec3::Y));

        let a = world.spawn((Transform(Affine3A::IDENTITY),));
        let b = world.spawn((Transform(Affine3A::IDENTITY), Parent(a)));
        let _ = world.insert_one(a, Parent(b));
        assert!(world_from_local(&world, a).is_finite());
    }
}
