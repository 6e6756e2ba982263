//! Transform propagation: fills `GlobalTransform` from `Transform` and `Parent`.

use crate::components::{GlobalTransform, Parent, Transform};
use hecs::{Entity, World};
use lucent_geom::Affine3A;

/// Longest parent chain followed; deeper chains (or cycles) stop here.
const MAX_HIERARCHY_DEPTH: usize = 64;

/// Computes `GlobalTransform = parent's GlobalTransform * Transform` for every
/// entity with a [`Transform`]. Entities without a parent, or whose parent
/// has no transform, use their own transform. Parent cycles cannot hang it:
/// chains are followed at most 64 levels.
pub fn update_global_transforms(world: &mut World) {
    let globals: Vec<(Entity, Affine3A)> = world
        .query::<(Entity, &Transform)>()
        .iter()
        .map(|(entity, _)| (entity, world_from_local(world, entity)))
        .collect();
    for (entity, m) in globals {
        // The entity came from the query above, so it exists.
        let _ = world.insert_one(entity, GlobalTransform(m));
    }
}

/// The world-from-object transform of `entity`, following `Parent` links
/// (at most 64 levels, so cycles terminate). Identity without a transform.
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
        update_global_transforms(&mut world);
        fn g(world: &World, e: Entity) -> Option<Affine3A> {
            world.get::<&GlobalTransform>(e).map(|g| g.0).ok()
        }
        let p = g(&world, child).map(|m| m.transform_point3(Vec3::ONE));
        assert_eq!(p, Some(Vec3::new(3.0, 2.0, 2.0)));
        assert_eq!(g(&world, orphan), Some(Affine3A::from_translation(Vec3::Y)));

        let a = world.spawn((Transform(Affine3A::IDENTITY),));
        let b = world.spawn((Transform(Affine3A::IDENTITY), Parent(a)));
        let _ = world.insert_one(a, Parent(b));
        update_global_transforms(&mut world);
        assert!(g(&world, a).is_some());
    }
}
