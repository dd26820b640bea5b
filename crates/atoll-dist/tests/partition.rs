//! Partitioning: every triangle of every instance exactly once, budgets
//! respected, big objects split, deterministic; `min_parts` and `plan`.

use atoll_bvh::{part_bytes, ByteModel, SceneBvh, ScenePart};
use atoll_dist::{
    min_parts, partition, plan, plan_partitioned, Partition, PartitionError, PartitionOptions, Plan, Strategy,
};
use atoll_scene::{Instance, Object, ObjectId, Scene, TextureImage, TriangleMesh};
use glam::{Affine3A, Vec2, Vec3};

const MODEL: ByteModel = ByteModel::CPU;

/// An `n` × `n` grid of quads with normals and uvs, offset by `z`.
fn grid(name: &str, n: u32, z: f32) -> TriangleMesh {
    let mut m = TriangleMesh { name: name.into(), ..Default::default() };
    for y in 0..=n {
        for x in 0..=n {
            m.positions.push(Vec3::new(x as f32, y as f32, z));
            m.normals.push(Vec3::Z);
            m.uvs.push(Vec2::new(x as f32, y as f32) / n as f32);
        }
    }
    for y in 0..n {
        for x in 0..n {
            let a = y * (n + 1) + x;
            let b = a + n + 1;
            m.indices.push([a, a + 1, b]);
            m.indices.push([a + 1, b + 1, b]);
        }
    }
    m
}

fn object(scene: &mut Scene, name: &str, meshes: Vec<TriangleMesh>) -> ObjectId {
    let meshes = meshes.into_iter().map(|m| scene.add_mesh(m)).collect();
    scene.add_object(Object { name: name.into(), meshes })
}

fn place(scene: &mut Scene, object: ObjectId, x: f32) {
    scene.instances.push(Instance::new(object, Affine3A::from_translation(Vec3::new(x, 0.0, 1.0))));
}

/// One huge ground object (a 48 × 48 grid, 4608 triangles, and a small
/// second mesh) and a dozen small objects, some instanced several times.
fn ground_scene() -> Scene {
    let mut scene = Scene::default();
    let ground = object(&mut scene, "ground", vec![grid("terrain", 48, 0.0), grid("kerb", 6, 0.1)]);
    scene.instances.push(Instance::new(ground, Affine3A::IDENTITY));
    for k in 0..12u32 {
        let o = object(&mut scene, &format!("thing{k}"), vec![grid("thing", 2 + k % 5, 0.0)]);
        for copy in 0..=k % 4 {
            place(&mut scene, o, (k * 4 + copy) as f32);
        }
    }
    // An object never placed: no part needs it.
    object(&mut scene, "unplaced", vec![grid("unplaced", 3, 0.0)]);
    scene
}

fn whole_bytes(scene: &Scene) -> u64 {
    part_bytes(scene, &ScenePart::whole(scene), &MODEL)
}

/// Enumerates (instance, mesh, triangle) per part through the `ScenePart`
/// semantics and checks that every triangle of every instance is held by
/// exactly one part, that `owner` agrees, that the byte counts are the
/// model's, and that BVHs over the parts hold all the triangles rays see.
fn check_exactly_once(scene: &Scene, p: &Partition) {
    assert_eq!(p.parts.len(), p.bytes.len());
    // Per instance and mesh of its object, the owning part of each triangle.
    let mut owners: Vec<Vec<Vec<Option<usize>>>> = scene
        .instances
        .iter()
        .map(|inst| {
            scene.objects[inst.object as usize]
                .meshes
                .iter()
                .map(|&m| vec![None; scene.meshes[m as usize].indices.len()])
                .collect()
        })
        .collect();
    for (index, part) in p.parts.iter().enumerate() {
        assert_eq!(p.bytes[index], part_bytes(scene, part, &MODEL));
        let mut sorted = part.instances.clone();
        sorted.dedup();
        assert_eq!(sorted, part.instances, "instances sorted and listed once");
        for &i in &part.instances {
            let object = scene.instances[i as usize].object;
            let meshes = &scene.objects[object as usize].meshes;
            for r in part.object_ranges(scene, object) {
                let slot = meshes.iter().position(|&m| m == r.mesh).expect("a mesh of the object");
                for t in r.triangles {
                    let owner = &mut owners[i as usize][slot][t as usize];
                    assert_eq!(*owner, None, "instance {i} mesh {} triangle {t} in two parts", r.mesh);
                    *owner = Some(index);
                }
            }
        }
    }
    for (i, inst) in scene.instances.iter().enumerate() {
        for (slot, &mesh) in scene.objects[inst.object as usize].meshes.iter().enumerate() {
            for (t, &owner) in owners[i][slot].iter().enumerate() {
                assert!(owner.is_some(), "instance {i} mesh {mesh} triangle {t} in no part");
                assert_eq!(p.owner(i as u32, mesh, t as u32), owner);
            }
            let n = owners[i][slot].len() as u32;
            assert_eq!(p.owner(i as u32, mesh, n), None, "past the mesh's last triangle");
        }
    }
    assert_eq!(p.owner(scene.instances.len() as u32, 0, 0), None);
    let traced: u64 =
        p.parts.iter().map(|part| SceneBvh::build_part(scene, part).stats().instanced_triangles).sum();
    assert_eq!(traced, scene.stats().instanced_triangles);
}

#[test]
fn big_ground_object_is_split_to_fit_three_budgets() {
    let scene = ground_scene();
    let ground_mesh = scene.meshes[0].clone();
    let mut alone = Scene::default();
    let o = object(&mut alone, "ground mesh alone", vec![ground_mesh]);
    place(&mut alone, o, 0.0);
    let ground_bytes = whole_bytes(&alone);
    let budget = ground_bytes * 3 / 4;
    let options = PartitionOptions { budget: Some(budget), ..Default::default() };
    let p = partition(&scene, 3, &MODEL, &options).expect("three parts hold the scene");
    check_exactly_once(&scene, &p);
    assert!(p.bytes.iter().all(|&b| b <= budget), "{:?} over {budget}", p.bytes);
    // The ground object is in several parts, its terrain by triangle ranges.
    let with_ground: Vec<&ScenePart> = p.parts.iter().filter(|part| part.instances.contains(&0)).collect();
    assert!(with_ground.len() >= 2);
    let terrain_triangles = scene.meshes[0].indices.len() as u32;
    for part in with_ground {
        let (object, ranges) = &part.object_subsets[0];
        assert_eq!(*object, 0);
        assert!(ranges.iter().all(|r| r.mesh != 0 || r.triangles.len() < terrain_triangles as usize));
    }
    // Balanced: no part much above the mean.
    let mean = p.bytes.iter().sum::<u64>() / 3;
    assert!(*p.bytes.iter().max().unwrap() < mean * 3 / 2, "{:?}", p.bytes);
    // Deterministic.
    assert_eq!(partition(&scene, 3, &MODEL, &options).unwrap(), p);
}

#[test]
fn objects_split_by_meshes_before_triangle_ranges() {
    let mut scene = Scene::default();
    let meshes = (0..4).map(|k| grid(&format!("tile{k}"), 10, k as f32)).collect();
    let o = object(&mut scene, "tiles", meshes);
    place(&mut scene, o, 0.0);
    let total = whole_bytes(&scene);
    // Any two meshes together are above the threshold, one alone is not.
    let options = PartitionOptions { budget: None, split_threshold: Some(total / 3), ..Default::default() };
    let p = partition(&scene, 2, &MODEL, &options).unwrap();
    check_exactly_once(&scene, &p);
    for part in &p.parts {
        let (_, ranges) = &part.object_subsets[0];
        assert_eq!(ranges.len(), 2, "two whole meshes per part");
        assert!(ranges.iter().all(|r| r.triangles == (0..200)));
    }
}

#[test]
fn many_instances_of_little_geometry_split_by_instance_groups() {
    let mut scene = Scene::default();
    let grass = object(&mut scene, "grass", vec![grid("blade", 1, 0.0)]);
    for k in 0..300 {
        place(&mut scene, grass, k as f32);
    }
    let rock = object(&mut scene, "rock", vec![grid("rock", 8, 0.0)]);
    place(&mut scene, rock, -5.0);
    let p = partition(&scene, 3, &MODEL, &PartitionOptions::default()).unwrap();
    check_exactly_once(&scene, &p);
    // The grass is never cut into triangle ranges, but its instances are
    // spread over all three parts (each with the whole blade).
    assert!(p.parts.iter().all(|part| part.object_subsets.iter().all(|s| s.0 != grass)));
    let with_grass = p.parts.iter().filter(|part| part.instances.iter().any(|&i| i < 300)).count();
    assert_eq!(with_grass, 3);
}

#[test]
fn procedural_scenes_are_covered_exactly_once() {
    for k in [1, 2, 5] {
        let scene = atoll_scene::cornell::builtin_cornell_box();
        check_exactly_once(&scene, &partition(&scene, k, &MODEL, &PartitionOptions::default()).unwrap());
        let scene = atoll_scene::procedural::bench_scene(8_000);
        check_exactly_once(&scene, &partition(&scene, k, &MODEL, &PartitionOptions::default()).unwrap());
    }
    // More parts than pieces: some parts stay empty, still correct.
    let mut scene = Scene::default();
    let o = object(&mut scene, "tiny", vec![grid("tiny", 1, 0.0)]);
    place(&mut scene, o, 0.0);
    let p = partition(&scene, 4, &MODEL, &PartitionOptions::default()).unwrap();
    check_exactly_once(&scene, &p);
}

#[test]
fn errors_say_what_does_not_fit_with_numbers() {
    let scene = ground_scene();
    let total = whole_bytes(&scene);
    assert_eq!(partition(&scene, 0, &MODEL, &PartitionOptions::default()), Err(PartitionError::NoParts(0)));

    // Two parts of a third of the scene each cannot hold it.
    let budget = total / 3;
    let err = partition(&scene, 2, &MODEL, &PartitionOptions { budget: Some(budget), ..Default::default() })
        .unwrap_err();
    assert!(matches!(err, PartitionError::DoesNotFit { parts: 2, .. }), "{err:?}");
    let message = err.to_string();
    assert!(message.contains("2 parts") && message.contains(&format!("({budget} bytes)")), "{message}");

    // The terrain's vertices alone exceed the budget: no split helps.
    let vertices = 49 * 49 * 32;
    let err =
        partition(&scene, 8, &MODEL, &PartitionOptions { budget: Some(vertices), ..Default::default() })
            .unwrap_err();
    let PartitionError::PieceTooBig { ref what, needed, budget } = err else { panic!("{err:?}") };
    assert!(what.contains("mesh 0 ('terrain'") && what.contains("object 0 ('ground')"), "{what}");
    assert!(needed > budget && budget == vertices);
    let message = err.to_string();
    assert!(message.contains(&format!("({needed} bytes)")) && message.contains("per device"), "{message}");
}

#[test]
fn min_parts_is_the_smallest_that_fits() {
    let scene = ground_scene();
    let total = whole_bytes(&scene);
    assert_eq!(min_parts(&scene, &MODEL, total, 8), Some(1));
    assert_eq!(min_parts(&scene, &MODEL, total / 100, 8), None);
    let budget = total * 2 / 5;
    let k = min_parts(&scene, &MODEL, budget, 8).expect("fits in 8");
    assert!(k >= 3, "{k} parts of {budget} for {total}");
    let options = PartitionOptions { budget: Some(budget), ..Default::default() };
    assert!(partition(&scene, k, &MODEL, &options).is_ok());
    assert!(partition(&scene, k - 1, &MODEL, &options).is_err());
}

#[test]
fn every_part_holds_the_texture_images() {
    let plain = ground_scene();
    let mut scene = ground_scene();
    // 64 × 64 float texels, 64 KiB: every device shades any material, so every part holds them.
    scene.textures.add_image(TextureImage::from_linear("t", 64, 64, vec![[0.5; 4]; 64 * 64]));
    let tex = 64 * 64 * 16;
    assert_eq!(whole_bytes(&scene), whole_bytes(&plain) + tex);
    let budget = whole_bytes(&plain) * 2 / 5;
    let k = min_parts(&plain, &MODEL, budget, 8).expect("fits in 8");
    let options = PartitionOptions { budget: Some(budget + tex), ..Default::default() };
    let p = partition(&scene, k, &MODEL, &options).expect("the same parts with room for the images");
    check_exactly_once(&scene, &p);
    assert!(p.bytes.iter().all(|&b| b > tex && b <= budget + tex), "{:?}", p.bytes);
    // A budget the images alone fill holds no geometry.
    assert_eq!(min_parts(&scene, &MODEL, tex, 8), None);
}

#[test]
fn plan_replicates_when_it_fits_else_rings_with_islands() {
    let scene = ground_scene();
    let total = whole_bytes(&scene);
    assert_eq!(plan(&scene, &MODEL, 4, None, None), Ok(Plan::Replicate));
    assert_eq!(plan(&scene, &MODEL, 4, Some(total), Some(Strategy::Auto)), Ok(Plan::Replicate));
    let budget = total * 2 / 5;
    let k = min_parts(&scene, &MODEL, budget, 8).unwrap();
    assert_eq!(plan(&scene, &MODEL, 8, Some(budget), None), Ok(Plan::Ring { k, islands: 8 / k }));
    assert_eq!(plan(&scene, &MODEL, k, Some(budget), None), Ok(Plan::Ring { k, islands: 1 }));
    let err = plan(&scene, &MODEL, k - 1, Some(budget), None).unwrap_err();
    assert!(matches!(err, PartitionError::TooFewDevices { .. }), "{err:?}");
    assert!(err.to_string().contains(&format!("{} devices", k - 1)), "{err}");
    assert_eq!(plan(&scene, &MODEL, 0, None, None), Err(PartitionError::NoParts(0)));
    // The partition that found K comes with the plan, as made afresh.
    let (ring, found) = plan_partitioned(&scene, &MODEL, 8, Some(budget), None).unwrap();
    assert_eq!(ring, Plan::Ring { k, islands: 8 / k });
    let options = PartitionOptions { budget: Some(budget), ..Default::default() };
    assert_eq!(found, Some(partition(&scene, k, &MODEL, &options).unwrap()));
    assert_eq!(plan_partitioned(&scene, &MODEL, 4, None, None).unwrap(), (Plan::Replicate, None));

    // Forced.
    assert_eq!(plan(&scene, &MODEL, 4, None, Some(Strategy::Ring)), Ok(Plan::Ring { k: 4, islands: 1 }));
    assert_eq!(
        plan(&scene, &MODEL, 5, Some(total), Some(Strategy::Ring)),
        Ok(Plan::Ring { k: 2, islands: 2 })
    );
    assert_eq!(plan(&scene, &MODEL, 4, None, Some(Strategy::Replicate)), Ok(Plan::Replicate));
    let err = plan(&scene, &MODEL, 4, Some(budget), Some(Strategy::Replicate)).unwrap_err();
    assert_eq!(err, PartitionError::ReplicaTooBig { needed: total, budget });
    assert!(err.to_string().contains(&format!("({total} bytes)")), "{err}");
}

#[test]
fn strategies_parse_from_their_names() {
    assert_eq!("auto".parse(), Ok(Strategy::Auto));
    assert_eq!(" Replicate ".parse(), Ok(Strategy::Replicate));
    assert_eq!("RING".parse(), Ok(Strategy::Ring));
    for name in Strategy::NAMES {
        assert_eq!(name.parse::<Strategy>().unwrap().to_string(), name);
    }
    assert_eq!(" Shared".parse(), Ok(Strategy::Shared));
    let err = "cycle".parse::<Strategy>().unwrap_err();
    assert_eq!(
        err.to_string(),
        "unknown distribution strategy 'cycle': expected auto, replicate, ring or shared"
    );
}

/// The heaviest piece goes to part 0 (`RingOrder::Home` traces every ray
/// there first: on a landscape, the ground). With a threshold splitting
/// nothing, the ground object is that piece.
#[test]
fn the_heaviest_piece_goes_to_part_zero() {
    let scene = ground_scene();
    let options = PartitionOptions { split_threshold: Some(u64::MAX), ..Default::default() };
    for parts in [2, 3] {
        let p = partition(&scene, parts, &MODEL, &options).unwrap();
        check_exactly_once(&scene, &p);
        assert_eq!(p.owner(0, 0, 0), Some(0), "{parts} parts: the ground is on part 0");
    }
}

/// Balanced by bytes plus a cost per instance, a ground and light objects
/// with many instances no longer put every instance on the part without
/// the ground (what bytes alone do: the landscape's plants, BENCHMARKS.md);
/// every triangle is still placed exactly once.
#[test]
fn instance_costs_spread_instanced_objects_over_the_parts() {
    let mut scene = Scene::default();
    let ground = object(&mut scene, "ground", vec![grid("terrain", 48, 0.0)]);
    place(&mut scene, ground, 0.0);
    for kind in 0..6 {
        let plant = object(&mut scene, &format!("plant{kind}"), vec![grid("leaf", 1, 0.0)]);
        for copy in 0..60 {
            place(&mut scene, plant, (kind * 60 + copy) as f32 * 0.1);
        }
    }
    // Whole objects: the ground alone outweighs all the plants in bytes.
    let whole = PartitionOptions { split_threshold: Some(u64::MAX), ..Default::default() };
    let bytes_only = partition(&scene, 2, &MODEL, &whole).unwrap();
    assert_eq!(bytes_only.parts[0].instances, vec![0], "by bytes: the ground alone on part 0");
    let costed = partition(&scene, 2, &MODEL, &PartitionOptions { instance_cost: 4 << 10, ..whole }).unwrap();
    check_exactly_once(&scene, &costed);
    let plants_on = |p: usize| costed.parts[p].instances.iter().filter(|&&i| i != 0).count();
    assert!(
        plants_on(0) >= 60 && plants_on(1) >= 60,
        "plants per part: {} and {}",
        plants_on(0),
        plants_on(1)
    );
    assert_eq!(costed.owner(0, 0, 0), Some(0), "the ground stays on part 0");
}
