//! True displacement on a demand-loading replica (a distributed render's worker): its objects'
//! meshes are not here before the frame, so it cannot dice them. Its master displaces them
//! (`true_displacement`) and each update says which of the world's instances are displaced and
//! into which of the master's scene objects; a new displaced mesh travels as a summary, as any
//! demand-loaded object does ([`crate::accel::object::MeshSummary`]), and the worker fetches it,
//! with the BVH the master built, when a ray first reaches it. The worker's world then traces and
//! shades those instances as the master's world does: the same mesh, the same tree, the same
//! parts, displacement not run again at their hits.
//!
//! The master's scene objects are the fetch keys ([`DISPLACED_MESH_KEY`] set, apart from the
//! context objects' keys). Both sides forget a displaced mesh that no instance of a frame uses:
//! the master sends it again when an instance uses it again.

use super::world::{InstanceParts, World};
use crate::accel::object::{MeshSource, MeshSummary};
use crate::geometry::Mesh;
use crate::scene::ObjectId;
use std::collections::HashMap;
use std::sync::Arc;

/// Set in the fetch key of a displaced mesh: the rest is the master's scene object holding it.
/// Context objects are fetched by their index, which stays below it.
pub const DISPLACED_MESH_KEY: u32 = 1 << 31;

/// The most triangles a master dices one source triangle into: a count above it is a damaged
/// update.
const MOST_PER_SOURCE: u32 = super::true_displacement::MAX_DICED_TRIANGLES as u32;

/// What a demand-loading replica knows of its master's displaced meshes, kept from update to
/// update: which instances are displaced and into what, and the scene objects standing for the
/// displaced meshes here.
#[derive(Default)]
pub struct RemoteDisplacements {
    /// The world's truly displaced instances (their index) and, for each, the master's scene
    /// object holding its displaced mesh.
    instances: Vec<(u32, u32)>,
    /// By the master's scene object: its displaced mesh.
    meshes: HashMap<u32, RemoteMesh>,
    /// Scene objects here of displaced meshes no longer used, to empty and use again.
    unused: Vec<ObjectId>,
    /// Scene objects here emptied, to use again.
    free: Vec<ObjectId>,
}

struct RemoteMesh {
    summary: MeshSummary,
    /// How many of its triangles each of its source mesh's triangles was diced into.
    per_source: Vec<u32>,
    /// The object standing for it here, once placed.
    object: Option<ObjectId>,
}

/// A displaced mesh as an update announces it: the master's scene object, the mesh's summary and
/// how many of its triangles each source triangle was diced into (they come in source order).
pub type AnnouncedMesh = (u32, MeshSummary, Vec<u32>);

impl RemoteDisplacements {
    /// Whether no instance is displaced and nothing is left to let go.
    pub fn is_empty(&self) -> bool {
        self.instances.is_empty() && self.unused.is_empty()
    }

    /// Takes an update's displaced instances (all of them) and the displaced meshes new since the
    /// last update. A mesh no instance uses any more is let go. Errors name what does not hold
    /// together (an instance of a mesh never announced, an impossible count).
    pub fn update(&mut self, instances: Vec<(u32, u32)>, meshes: Vec<AnnouncedMesh>) -> Result<(), String> {
        for (slot, summary, per_source) in meshes {
            if let Some(count) = per_source.iter().find(|&&n| n > MOST_PER_SOURCE) {
                return Err(format!("displaced mesh {slot}: {count} triangles diced from one"));
            }
            let diced: u64 = per_source.iter().map(|&n| u64::from(n)).sum();
            if diced != u64::from(summary.triangles) {
                return Err(format!(
                    "displaced mesh {slot}: {} triangles, where its source triangles make {diced}",
                    summary.triangles
                ));
            }
            if slot & DISPLACED_MESH_KEY != 0 {
                return Err(format!("displaced mesh {slot}: no such scene object"));
            }
            let object = self.meshes.remove(&slot).and_then(|m| m.object);
            self.meshes.insert(slot, RemoteMesh { summary, per_source, object });
        }
        if let Some(&(instance, slot)) = instances.iter().find(|(_, slot)| !self.meshes.contains_key(slot)) {
            return Err(format!("instance {instance}: displaced mesh {slot} was never sent"));
        }
        let used: std::collections::HashSet<u32> = instances.iter().map(|&(_, slot)| slot).collect();
        let mut gone: Vec<u32> = self.meshes.keys().copied().filter(|slot| !used.contains(slot)).collect();
        gone.sort_unstable();
        for slot in gone {
            if let Some(object) = self.meshes.remove(&slot).and_then(|m| m.object) {
                self.unused.push(object);
            }
        }
        self.instances = instances;
        Ok(())
    }
}

/// Makes the displaced instances of `world` (built from a demand-loading replica, after
/// [`World::prepare`]) traced and shaded as their master's: each takes a demand-loaded object of
/// its displaced mesh, fetched from `source`. Prepares the world again where any instance
/// changed. Errors where an update does not fit the world (an instance it does not have, a mesh
/// of another size than its source diced at its rate).
pub fn place_remote(
    world: &mut World,
    remote: &mut RemoteDisplacements,
    source: &Arc<dyn MeshSource>,
) -> Result<(), String> {
    for object in remote.unused.drain(..) {
        let emptied = Mesh::from_triangles(Vec::new(), Vec::new())
            .map_err(|e| e.to_string())
            .and_then(|empty| world.scene.set_object_mesh(object, empty).map_err(|e| e.to_string()));
        if emptied.is_ok() {
            remote.free.push(object);
        }
    }
    let mut changed = false;
    for &(index, slot) in &remote.instances {
        let Some(mesh) = remote.meshes.get_mut(&slot) else {
            return Err(format!("instance {index}: displaced mesh {slot} was never sent"));
        };
        let key = DISPLACED_MESH_KEY | slot;
        // A scene made again (a frame that failed kept none) no longer holds the object.
        let placed =
            mesh.object.filter(|&o| {
                world.scene.objects().get(o.0 as usize).is_some_and(|object| {
                    object.remote_key() == Some(key) && object.digest() == Some(&mesh.summary.digest)
                })
            });
        let object = match placed {
            Some(object) => object,
            None => {
                let summary = mesh.summary.clone();
                let object = match remote.free.pop() {
                    Some(free) if world.scene.set_object_remote(free, summary.clone(), key, source.clone()).is_ok() => {
                        free
                    }
                    _ => world.scene.add_remote_object(summary, key, source.clone()),
                };
                mesh.object = Some(object);
                object
            }
        };
        let inst = world
            .instances
            .get_mut(index as usize)
            .ok_or_else(|| format!("displaced instance {index} of a world of fewer"))?;
        let source_triangles = world.scene.objects().get(inst.object as usize).map_or(0, |o| o.triangle_count());
        if inst.displaced {
            return Err(format!("instance {index}: displaced here and by the master"));
        }
        if source_triangles != mesh.per_source.len() {
            return Err(format!(
                "instance {index}: a displaced mesh diced from {} triangles for {source_triangles}",
                mesh.per_source.len()
            ));
        }
        world.scene.set_instance_object(index, object).map_err(|e| e.to_string())?;
        inst.object = object.0;
        inst.displaced = true;
        inst.parts = inst.parts.take().map(|parts| diced_parts(&parts, &mesh.per_source));
        changed = true;
    }
    if changed {
        world.prepare();
    }
    Ok(())
}

/// The parts of a mesh whose source triangles were diced into `per_source` triangles each, in
/// source order: each diced triangle in its source triangle's part.
fn diced_parts(parts: &InstanceParts, per_source: &[u32]) -> InstanceParts {
    let of = parts.of_triangle.iter().zip(per_source).flat_map(|(&p, &n)| std::iter::repeat_n(p, n as usize)).collect();
    InstanceParts { of_triangle: of, materials: parts.materials.clone() }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn summary(triangles: usize) -> MeshSummary {
        let positions = vec![glam::Vec3::ZERO, glam::Vec3::X, glam::Vec3::Y];
        let mesh = Mesh::from_triangles(positions, vec![[0, 1, 2]; triangles]).expect("a mesh");
        MeshSummary::of(&mesh, None)
    }

    #[test]
    fn an_update_names_only_meshes_it_or_an_earlier_one_announced() {
        let mut remote = RemoteDisplacements::default();
        let err = remote.update(vec![(0, 7)], vec![]).expect_err("never announced");
        assert!(err.contains("displaced mesh 7 was never sent"), "{err}");
        remote.update(vec![(0, 7), (3, 7)], vec![(7, summary(4), vec![4])]).expect("announced");
        // Announced before: the next update need not send it again.
        remote.update(vec![(1, 7)], vec![]).expect("sent before");
        assert!(!remote.is_empty());
    }

    #[test]
    fn impossible_counts_and_keys_are_errors() {
        let mut remote = RemoteDisplacements::default();
        for count in [MOST_PER_SOURCE + 1, u32::MAX] {
            let err = remote.update(vec![], vec![(1, summary(1), vec![count])]).expect_err("a bad count");
            assert!(err.contains("triangles diced from one"), "{err}");
        }
        let err = remote.update(vec![], vec![(1, summary(5), vec![4])]).expect_err("counts of another sum");
        assert!(err.contains("5 triangles, where its source triangles make 4"), "{err}");
        let err = remote.update(vec![], vec![(1, summary(5), vec![u32::MAX, u32::MAX])]).expect_err("overflowing");
        assert!(err.contains("triangles diced from one"), "{err}");
        let err = remote.update(vec![], vec![(DISPLACED_MESH_KEY | 1, summary(1), vec![1])]).expect_err("a bad object");
        assert!(err.contains("no such scene object"), "{err}");
    }

    #[test]
    fn meshes_no_instance_uses_are_let_go() {
        let mut remote = RemoteDisplacements::default();
        remote.update(vec![(0, 1), (1, 2)], vec![(1, summary(1), vec![1]), (2, summary(4), vec![3, 1])]).expect("two");
        // Placed here as objects 5 and 6.
        remote.meshes.get_mut(&1).expect("mesh 1").object = Some(ObjectId(5));
        remote.meshes.get_mut(&2).expect("mesh 2").object = Some(ObjectId(6));
        remote.update(vec![(0, 2)], vec![]).expect("one");
        assert_eq!(remote.unused, [ObjectId(5)]);
        assert!(!remote.meshes.contains_key(&1));
        // Sent again, it is announced again.
        assert!(remote.update(vec![(0, 1)], vec![]).is_err());
        remote.update(vec![], vec![]).expect("none");
        assert_eq!(remote.unused, [ObjectId(5), ObjectId(6)]);
        assert!(!remote.is_empty(), "objects are left to let go");
    }
}
