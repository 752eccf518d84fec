//! A bounding volume hierarchy over triangles for segment queries.

use crate::vec3::Vec3;

const LEAF_SIZE: usize = 4;

#[derive(Clone, Copy, Debug)]
struct Node {
    lo: Vec3,
    hi: Vec3,
    /// Leaf: first item; inner: index of the left child (right = left + 1).
    first: u32,
    /// Leaf: item count; inner: 0.
    count: u32,
}

/// Axis-aligned bounding-box tree over triangles (median split on the longest axis).
#[derive(Clone, Debug)]
pub struct TriangleBvh {
    nodes: Vec<Node>,
    items: Vec<u32>,
    pad: f64,
}

impl TriangleBvh {
    /// Builds the tree; boxes are padded by `1e-9` of the scene size so that the exact
    /// predicates, not box rounding, decide grazing contacts.
    pub fn new(positions: &[Vec3], triangles: &[[u32; 3]]) -> Self {
        let boxes: Vec<(Vec3, Vec3)> = triangles
            .iter()
            .map(|t| {
                let mut lo = [f64::INFINITY; 3];
                let mut hi = [f64::NEG_INFINITY; 3];
                for &v in t {
                    let p = positions[v as usize];
                    for c in 0..3 {
                        lo[c] = lo[c].min(p[c]);
                        hi[c] = hi[c].max(p[c]);
                    }
                }
                (lo, hi)
            })
            .collect();
        let (slo, shi) = crate::mesh::bounding_box(positions);
        let size = (0..3).map(|c| shi[c] - slo[c]).fold(0.0, f64::max);
        let pad = 1e-9 * size.max(f64::MIN_POSITIVE);
        let mut items: Vec<u32> = (0..triangles.len() as u32).collect();
        let mut nodes = vec![Node { lo: [0.0; 3], hi: [0.0; 3], first: 0, count: 0 }];
        build(&mut nodes, 0, &mut items, 0, &boxes, pad);
        Self { nodes, items, pad }
    }

    /// Calls `hit(item)` for every triangle whose box meets segment (p, q), stopping and
    /// returning true as soon as `hit` returns true.
    pub fn any_on_segment(&self, p: Vec3, q: Vec3, mut hit: impl FnMut(u32) -> bool) -> bool {
        let d = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
        let inv = [1.0 / d[0], 1.0 / d[1], 1.0 / d[2]];
        let mut stack = [0u32; 64];
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let node = &self.nodes[stack[sp] as usize];
            if !segment_box(p, d, inv, node.lo, node.hi) {
                continue;
            }
            if node.count > 0 {
                let s = node.first as usize;
                for &it in &self.items[s..s + node.count as usize] {
                    if hit(it) {
                        return true;
                    }
                }
            } else if sp + 2 <= stack.len() {
                stack[sp] = node.first;
                stack[sp + 1] = node.first + 1;
                sp += 2;
            }
        }
        false
    }

    /// The box padding used.
    pub fn padding(&self) -> f64 {
        self.pad
    }
}

fn build(
    nodes: &mut Vec<Node>,
    at: usize,
    items: &mut [u32],
    offset: usize,
    boxes: &[(Vec3, Vec3)],
    pad: f64,
) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    let mut clo = [f64::INFINITY; 3];
    let mut chi = [f64::NEG_INFINITY; 3];
    for &it in items.iter() {
        let (a, b) = boxes[it as usize];
        for c in 0..3 {
            lo[c] = lo[c].min(a[c]);
            hi[c] = hi[c].max(b[c]);
            let m = 0.5 * (a[c] + b[c]);
            clo[c] = clo[c].min(m);
            chi[c] = chi[c].max(m);
        }
    }
    for c in 0..3 {
        lo[c] -= pad;
        hi[c] += pad;
    }
    if items.len() <= LEAF_SIZE {
        nodes[at] = Node { lo, hi, first: offset as u32, count: items.len() as u32 };
        return;
    }
    let axis = (0..3).max_by(|&a, &b| (chi[a] - clo[a]).total_cmp(&(chi[b] - clo[b]))).unwrap_or(0);
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |&x, &y| {
        let cx = boxes[x as usize].0[axis] + boxes[x as usize].1[axis];
        let cy = boxes[y as usize].0[axis] + boxes[y as usize].1[axis];
        cx.total_cmp(&cy)
    });
    let left = nodes.len();
    nodes.push(Node { lo: [0.0; 3], hi: [0.0; 3], first: 0, count: 0 });
    nodes.push(Node { lo: [0.0; 3], hi: [0.0; 3], first: 0, count: 0 });
    nodes[at] = Node { lo, hi, first: left as u32, count: 0 };
    let (l, r) = items.split_at_mut(mid);
    build(nodes, left, l, offset, boxes, pad);
    build(nodes, left + 1, r, offset + mid, boxes, pad);
}

/// Slab test of the segment p + t d, t in [0, 1], against a box.
#[inline]
fn segment_box(p: Vec3, d: Vec3, inv: Vec3, lo: Vec3, hi: Vec3) -> bool {
    let mut t0 = 0.0f64;
    let mut t1 = 1.0f64;
    for c in 0..3 {
        if d[c] == 0.0 {
            if p[c] < lo[c] || p[c] > hi[c] {
                return false;
            }
            continue;
        }
        let (mut a, mut b) = ((lo[c] - p[c]) * inv[c], (hi[c] - p[c]) * inv[c]);
        if a > b {
            std::mem::swap(&mut a, &mut b);
        }
        t0 = t0.max(a);
        t1 = t1.min(b);
        if t0 > t1 {
            return false;
        }
    }
    true
}
