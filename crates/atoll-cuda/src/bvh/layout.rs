//! The GPU BVH's traversal layout (mirrors `kernels/bvh.cuh`) and the build
//! tree's constants (mirrors `kernels/lbvh.cuh`). Both headers hold a block
//! generated from this file (`src/header.rs`), so sizes, offsets and
//! constants are defined once.
//!
//! After Aila & Laine 2009: a binary node stores the boxes of its two
//! children and their links (64 bytes), so one fetch decides which children
//! a ray visits. A link `0 <= l < LINK_DONE` is a node index; `l < 0` a
//! leaf of up to [`MAX_LEAF_PRIMS`] consecutive records:
//! `!l = (first << 2) | (count - 1)`. In a BLAS, `first` counts from the
//! record base of the TLAS record that entered it
//! ([`GpuTlasInstance::tri_base`]: 0 in a BVH built whole, each piece's
//! first record in one built in pieces).

use bytemuck::{Pod, Zeroable};

#[cfg(test)]
use crate::header::struct_asserts;
#[cfg(test)]
use crate::layout::{field_layout, FieldLayout};

/// Stack bottom of every traversal; also the root link of an empty tree.
pub(crate) const LINK_DONE: i32 = 0x7654_3210;
/// Pushed when traversal enters an instance; popping it returns to the TLAS.
#[cfg(test)]
pub(crate) const LINK_INSTANCE_END: i32 = 0x7654_3211;
/// Most primitives in one leaf (two bits of a leaf link).
pub(crate) const MAX_LEAF_PRIMS: u32 = 4;
/// Entries of a traversal stack (TLAS and BLAS depth together).
#[cfg(test)]
pub(crate) const TRAVERSAL_STACK: u32 = 96;
/// Leaf links index records below `1 << LEAF_FIRST_BITS`.
pub(crate) const LEAF_FIRST_BITS: u32 = 29;

/// "No node" in the build tree (parent of a root, children of a spare slot).
pub(crate) const BUILD_NONE: u32 = u32::MAX;
/// In a build node's packed count: the SAH prefers this subtree as one leaf.
pub(crate) const BUILD_LEAF_BIT: u32 = 1 << 31;
pub(crate) const BUILD_COUNT_MASK: u32 = !BUILD_LEAF_BIT;

/// Which ray/triangle test the triangle records are prepared for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum TriangleTest {
    /// Möller–Trumbore, bit for bit the CPU's `atoll_bvh::TriAccel::intersect`:
    /// records are (p0, p1 - p0, p2 - p0). CPU and GPU find the same hits.
    #[default]
    Exact,
    /// Woop's unit-triangle test (rows of the world-to-triangle map): fewer
    /// operations per test; hits agree with the CPU's up to rounding.
    Woop,
}

impl TriangleTest {
    /// The `test` argument of `lbvh_emit_triangles` (TRI_EXACT / TRI_WOOP).
    pub(crate) fn kernel_value(self) -> i32 {
        match self {
            TriangleTest::Exact => 0,
            TriangleTest::Woop => 1,
        }
    }

    /// Kernel name suffix (`trace_closest_ww_exact`).
    pub(crate) fn suffix(self) -> &'static str {
        match self {
            TriangleTest::Exact => "exact",
            TriangleTest::Woop => "woop",
        }
    }
}

/// `a[3]`'s bits in the record of a curve piece's proxy triangle (a NaN
/// no triangle record holds): traversal tests curve piece `a[0]`'s bits
/// (an index into the scene's `curves` table) instead of a triangle.
pub const CURVE_RECORD_MARKER: u32 = 0x7f80_c0ed;

/// The record standing for curve piece `index` (see [`CURVE_RECORD_MARKER`]).
pub(crate) fn curve_record(index: u32) -> GpuTriRecord {
    GpuTriRecord {
        a: [f32::from_bits(index), 0.0, 0.0, f32::from_bits(CURVE_RECORD_MARKER)],
        ..Default::default()
    }
}

/// A traversal node: both children's boxes and links (64 bytes).
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuBvhNode {
    /// left.min.x, left.max.x, left.min.y, left.max.y
    pub left_xy: [f32; 4],
    /// right.min.x, right.max.x, right.min.y, right.max.y
    pub right_xy: [f32; 4],
    /// left.min.z, left.max.z, right.min.z, right.max.z
    pub z: [f32; 4],
    /// left link, right link, 0, 0
    pub links: [i32; 4],
}

/// A triangle prepared for the test named by [`TriangleTest`] (48 bytes).
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuTriRecord {
    pub a: [f32; 4],
    pub b: [f32; 4],
    pub c: [f32; 4],
}

/// [`GpuTlasInstance::transform`]: how a ray enters the instance.
pub mod transform {
    /// Through `world_to_object`.
    pub const AFFINE: u32 = 0;
    /// Unchanged (`object_to_world` is the identity).
    pub const IDENTITY: u32 = 1;
    /// Through its motion's transform at the ray's time.
    pub const MOVING: u32 = 2;
}

/// A TLAS leaf: one instance (64 bytes).
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuTlasInstance {
    /// Row-major 3×4, copied from `GpuInstance::world_to_object`; for a
    /// moving instance ([`transform::MOVING`]) its first word holds the
    /// bits of its motion's index instead (the matrix is made per ray).
    pub world_to_object: [f32; 12],
    /// Root link of the instance's BLAS in the BLAS node array.
    pub blas_root: i32,
    /// Index into the scene's instances.
    pub instance: u32,
    /// How rays enter the instance ([`transform`]).
    pub transform: u32,
    /// Where the BLAS's triangle records start: its leaf links count from
    /// here, so each BLAS addresses `1 << LEAF_FIRST_BITS` records of its
    /// own and a BVH built in pieces holds more than that in all (0 for a
    /// BVH built whole).
    pub tri_base: u32,
}

const _: () = {
    assert!(std::mem::size_of::<GpuBvhNode>() == 64);
    assert!(std::mem::size_of::<GpuTriRecord>() == 48);
    assert!(std::mem::size_of::<GpuTlasInstance>() == 64);
};

// SAFETY (all three): `#[repr(C)]` plain-old-data (Pod): every bit pattern,
// zeros included, is a valid value; copied to and from the device as bytes.
unsafe impl cudarc::driver::DeviceRepr for GpuBvhNode {}
unsafe impl cudarc::driver::ValidAsZeroBits for GpuBvhNode {}
unsafe impl cudarc::driver::DeviceRepr for GpuTriRecord {}
unsafe impl cudarc::driver::ValidAsZeroBits for GpuTriRecord {}
unsafe impl cudarc::driver::DeviceRepr for GpuTlasInstance {}
unsafe impl cudarc::driver::ValidAsZeroBits for GpuTlasInstance {}

impl GpuBvhNode {
    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(GpuBvhNode { left_xy, right_xy, z, links })
    }

    /// The box of child 0 (left) or 1 (right) as (min, max).
    pub(crate) fn child_box(&self, child: usize) -> ([f32; 3], [f32; 3]) {
        let xy = if child == 0 { &self.left_xy } else { &self.right_xy };
        let (zlo, zhi) = (self.z[2 * child], self.z[2 * child + 1]);
        ([xy[0], xy[2], zlo], [xy[1], xy[3], zhi])
    }

    /// Builds a node from its children's boxes and links.
    pub(crate) fn new(boxes: [([f32; 3], [f32; 3]); 2], links: [i32; 2]) -> Self {
        let [(l0, l1), (r0, r1)] = boxes;
        GpuBvhNode {
            left_xy: [l0[0], l1[0], l0[1], l1[1]],
            right_xy: [r0[0], r1[0], r0[1], r1[1]],
            z: [l0[2], l1[2], r0[2], r1[2]],
            links: [links[0], links[1], 0, 0],
        }
    }
}

impl GpuTriRecord {
    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(GpuTriRecord { a, b, c })
    }
}

impl GpuTlasInstance {
    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(GpuTlasInstance { world_to_object, blas_root, instance, transform, tri_base })
    }
}

/// A link to a leaf of `count` (1..=4) records from `first`.
pub(crate) fn leaf_link(first: u32, count: u32) -> i32 {
    debug_assert!((1..=MAX_LEAF_PRIMS).contains(&count) && first < 1 << LEAF_FIRST_BITS);
    !(((first << 2) | (count - 1)) as i32)
}

/// What a link points at.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Link {
    Node(u32),
    Leaf {
        first: u32,
        count: u32,
    },
    /// `LINK_DONE` (an empty tree) or another marker.
    Marker(i32),
}

impl Link {
    pub(crate) fn decode(link: i32) -> Link {
        if link < 0 {
            let bits = !link as u32;
            Link::Leaf { first: bits >> 2, count: (bits & 3) + 1 }
        } else if link < LINK_DONE {
            Link::Node(link as u32)
        } else {
            Link::Marker(link)
        }
    }
}

#[cfg(test)]
fn const_int(ty: &str, name: &str, value: impl std::fmt::Display) -> String {
    format!("constexpr {ty} {name} = {value};\n")
}

/// The generated block of `kernels/bvh.cuh`: traversal constants and the
/// layout structs' asserts.
#[cfg(test)]
pub(crate) fn header_block() -> String {
    let mut s = String::new();
    s += &const_int("int", "LINK_DONE", LINK_DONE);
    s += &const_int("int", "LINK_INSTANCE_END", LINK_INSTANCE_END);
    s += &const_int("unsigned int", "MAX_LEAF_PRIMS", format!("{MAX_LEAF_PRIMS}u"));
    s += &const_int("int", "TRAVERSAL_STACK", TRAVERSAL_STACK);
    s += &const_int("unsigned int", "TRANSFORM_AFFINE", format!("{}u", transform::AFFINE));
    s += &const_int("unsigned int", "TRANSFORM_IDENTITY", format!("{}u", transform::IDENTITY));
    s += &const_int("unsigned int", "TRANSFORM_MOVING", format!("{}u", transform::MOVING));
    s += &struct_asserts("BvhNode", std::mem::size_of::<GpuBvhNode>(), &GpuBvhNode::field_layout());
    s += &struct_asserts("TriRecord", std::mem::size_of::<GpuTriRecord>(), &GpuTriRecord::field_layout());
    s + &struct_asserts(
        "TlasInstance",
        std::mem::size_of::<GpuTlasInstance>(),
        &GpuTlasInstance::field_layout(),
    )
}

/// The generated block of `kernels/lbvh.cuh`: the build tree's constants.
#[cfg(test)]
pub(crate) fn build_header_block() -> String {
    let hex = |v: u32| format!("0x{v:08x}u");
    [
        const_int("unsigned int", "BUILD_NONE", hex(BUILD_NONE)),
        const_int("unsigned int", "BUILD_LEAF_BIT", hex(BUILD_LEAF_BIT)),
        const_int("unsigned int", "BUILD_COUNT_MASK", hex(BUILD_COUNT_MASK)),
    ]
    .concat()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn links_round_trip() {
        for (first, count) in [(0, 1), (5, 4), ((1 << LEAF_FIRST_BITS) - 1, 3)] {
            let link = leaf_link(first, count);
            assert!(link < 0);
            assert_eq!(Link::decode(link), Link::Leaf { first, count });
        }
        assert_eq!(Link::decode(0), Link::Node(0));
        assert_eq!(Link::decode(LINK_DONE - 1), Link::Node(LINK_DONE as u32 - 1));
        assert_eq!(Link::decode(LINK_DONE), Link::Marker(LINK_DONE));
        // The root link of a one-instance TLAS, which the host computes itself.
        assert_eq!(leaf_link(0, 1), -1);
    }

    #[test]
    fn node_boxes_round_trip() {
        let boxes = [([1.0, 2.0, 3.0], [4.0, 5.0, 6.0]), ([-1.0, -2.0, -3.0], [0.5, 0.25, 0.125])];
        let node = GpuBvhNode::new(boxes, [3, -7]);
        assert_eq!((node.child_box(0), node.child_box(1)), (boxes[0], boxes[1]));
        assert_eq!(node.links, [3, -7, 0, 0]);
    }

    #[test]
    fn header_blocks_name_the_constants() {
        let s = header_block();
        assert!(s.contains("constexpr int LINK_DONE = 1985229328;"), "{s}");
        assert!(s.contains("__builtin_offsetof(TlasInstance, blas_root) == 48"), "{s}");
        assert!(build_header_block().contains("BUILD_LEAF_BIT = 0x80000000u"));
    }
}
