//! Hierarchical evaluation of `B_k(x_o) = Σᵢ E′ᵢ·Aᵢ·b_k(|xᵢ − x_o|)` (Jensen & Buhler 2002).
//!
//! Summing every sample for every pixel costs pixels × samples (512² × 64k = 1.7·10¹⁰ terms).
//! Instead the samples go into an octree whose nodes keep the sum of their power `E′·A` (per
//! light group) and its centroid (weighted by power); a node whose points all lie within
//! `radius ≤ θ·d` of its centroid, d the distance from the centroid to x_o, is used as one
//! point at its centroid. The centroid makes the first-order error vanish, so the relative
//! error of a node is O(θ²·d²·|b″|/|b|), checked on an e^{−r} kernel by the unit test below;
//! the bake's default θ = 0.15 keeps the whole relit subsurface image (octree + PCA + f16)
//! close to the brute-force sum (tests/engine/subsurface.rs; figures in docs/measurements.md,
//! "Subsurface basis"). Samples with no light are not stored.

use glam::Vec3;

use crate::Rgb;

/// Points per leaf.
const LEAF: usize = 8;

#[derive(Clone, Copy, Debug)]
struct Node {
    /// Power-weighted centroid of the node's points.
    centroid: Vec3,
    /// Largest distance from the centroid to one of its points.
    radius: f32,
    /// Leaf: range of points; inner: range of children.
    first: u32,
    count: u32,
    leaf: bool,
}

impl Node {
    /// A slot reserved before its contents are known (the root before the build, children
    /// before their recursion), so a node's children stay contiguous.
    const PLACEHOLDER: Node = Node {
        centroid: Vec3::ZERO,
        radius: 0.0,
        first: 0,
        count: 0,
        leaf: true,
    };
}

/// The octree of one region's lit samples.
#[derive(Clone, Debug, Default)]
pub struct ScatterTree {
    nodes: Vec<Node>,
    points: Vec<Vec3>,
    /// Power `E′·A` per point and light group (point-major).
    power: Vec<Rgb>,
    /// Power per node and light group (node-major).
    node_power: Vec<Rgb>,
    groups: usize,
    /// Opening criterion θ: a node is used whole when radius ≤ θ·distance.
    pub theta: f32,
}

impl ScatterTree {
    /// Builds the tree over `points` with per-point, per-group power `power`
    /// (`points.len() × groups`). Points with zero power in every group are left out.
    pub fn build(points: &[Vec3], power: &[Rgb], groups: usize, theta: f32) -> ScatterTree {
        let mut idx: Vec<u32> = (0..points.len() as u32)
            .filter(|&i| {
                let p = &power[i as usize * groups..(i as usize + 1) * groups];
                p.iter().any(|v| *v != Rgb::ZERO)
            })
            .collect();
        let mut tree = ScatterTree {
            groups,
            theta,
            ..Default::default()
        };
        if idx.is_empty() {
            return tree;
        }
        tree.nodes.push(Node::PLACEHOLDER);
        let n = idx.len();
        build_node(&mut tree, points, power, &mut idx, 0, 0, n, 0);
        tree.points = idx.iter().map(|&i| points[i as usize]).collect();
        tree.power = idx
            .iter()
            .flat_map(|&i| {
                power[i as usize * groups..(i as usize + 1) * groups]
                    .iter()
                    .copied()
            })
            .collect();
        tree
    }

    /// Number of lit points stored.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether no point carries light.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Light groups per point.
    pub fn groups(&self) -> usize {
        self.groups
    }

    /// Adds `Σᵢ powerᵢ[g]·b_k(|xᵢ − x|)` into `out[g·k_count + k]` for every group g and basis
    /// k, with `eval(r, b)` writing `b_k(r)` for k < `k_count` into b. Returns the number of
    /// point and node terms summed (the cost).
    pub fn gather(
        &self,
        x: Vec3,
        k_count: usize,
        eval: &impl Fn(f32, &mut [f32]),
        out: &mut [Rgb],
    ) -> usize {
        if self.nodes.is_empty() {
            return 0;
        }
        let g_count = self.groups;
        let mut b = [0.0f32; 64];
        let b = &mut b[..k_count];
        let mut stack: Vec<u32> = Vec::with_capacity(64);
        stack.push(0);
        let mut terms = 0;
        let mut add = |r: f32, power: &[Rgb], b: &mut [f32]| {
            eval(r, b);
            for (g, p) in power.iter().enumerate() {
                if *p == Rgb::ZERO {
                    continue;
                }
                for (o, bk) in out[g * k_count..(g + 1) * k_count].iter_mut().zip(b.iter()) {
                    *o += *p * *bk;
                }
            }
        };
        while let Some(ni) = stack.pop() {
            let node = self.nodes[ni as usize];
            let d = node.centroid.distance(x);
            if node.radius <= self.theta * d {
                let p = &self.node_power[ni as usize * g_count..(ni as usize + 1) * g_count];
                add(d, p, b);
                terms += 1;
            } else if node.leaf {
                for i in node.first as usize..(node.first + node.count) as usize {
                    let p = &self.power[i * g_count..(i + 1) * g_count];
                    add(self.points[i].distance(x), p, b);
                    terms += 1;
                }
            } else {
                stack.extend(node.first..node.first + node.count);
            }
        }
        terms
    }
}

fn weight(p: &[Rgb]) -> f64 {
    p.iter().map(|v| (v.x + v.y + v.z) as f64).sum()
}

#[allow(clippy::too_many_arguments)]
fn build_node(
    tree: &mut ScatterTree,
    points: &[Vec3],
    power: &[Rgb],
    idx: &mut [u32],
    node: usize,
    lo: usize,
    hi: usize,
    depth: u32,
) {
    let g = tree.groups;
    let items = &idx[lo..hi];
    // Power sums and power-weighted centroid (plain centroid when the weights cancel).
    let mut sum = vec![Rgb::ZERO; g];
    let (mut c, mut wsum) = (glam::DVec3::ZERO, 0.0f64);
    let (mut bmin, mut bmax) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for &i in items {
        let p = &power[i as usize * g..(i as usize + 1) * g];
        for (s, v) in sum.iter_mut().zip(p) {
            *s += *v;
        }
        let w = weight(p).max(0.0);
        c += points[i as usize].as_dvec3() * w;
        wsum += w;
        bmin = bmin.min(points[i as usize]);
        bmax = bmax.max(points[i as usize]);
    }
    let centroid = if wsum > 0.0 {
        (c / wsum).as_vec3()
    } else {
        0.5 * (bmin + bmax)
    };
    let radius = items
        .iter()
        .map(|&i| points[i as usize].distance(centroid))
        .fold(0.0f32, f32::max);
    if tree.node_power.len() < (node + 1) * g {
        tree.node_power.resize((node + 1) * g, Rgb::ZERO);
    }
    tree.node_power[node * g..(node + 1) * g].copy_from_slice(&sum);
    let n = hi - lo;
    let size = (bmax - bmin).max_element();
    if n <= LEAF || depth >= 40 || !(size > 0.0) {
        tree.nodes[node] = Node {
            centroid,
            radius,
            first: lo as u32,
            count: n as u32,
            leaf: true,
        };
        return;
    }
    // Split into octants around the box centre.
    let mid = 0.5 * (bmin + bmax);
    let octant = |i: u32| -> usize {
        let p = points[i as usize];
        (p.x > mid.x) as usize | ((p.y > mid.y) as usize) << 1 | ((p.z > mid.z) as usize) << 2
    };
    idx[lo..hi].sort_by_key(|&i| octant(i));
    let mut ranges = Vec::with_capacity(8);
    let mut start = lo;
    while start < hi {
        let o = octant(idx[start]);
        let mut end = start;
        while end < hi && octant(idx[end]) == o {
            end += 1;
        }
        ranges.push((start, end));
        start = end;
    }
    let first_child = tree.nodes.len();
    for _ in &ranges {
        tree.nodes.push(Node::PLACEHOLDER);
    }
    tree.nodes[node] = Node {
        centroid,
        radius,
        first: first_child as u32,
        count: ranges.len() as u32,
        leaf: false,
    };
    for (c, (a, b)) in ranges.into_iter().enumerate() {
        build_node(tree, points, power, idx, first_child + c, a, b, depth + 1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clustered_sum_matches_brute_force() {
        // A 40×40 grid of points with varying power; kernel e^{−r}.
        let mut pts = Vec::new();
        let mut pw = Vec::new();
        for i in 0..40 {
            for j in 0..40 {
                pts.push(Vec3::new(i as f32 * 0.1, j as f32 * 0.1, 0.0));
                pw.push(Rgb::splat(1.0 + (i * j % 7) as f32));
            }
        }
        let eval = |r: f32, b: &mut [f32]| {
            b[0] = (-r).exp();
            b[1] = (-0.3 * r).exp();
        };
        for (theta, tol) in [(0.25f32, 2e-2), (0.1, 3e-3)] {
            let tree = ScatterTree::build(&pts, &pw, 1, theta);
            for x in [Vec3::new(1.0, 2.0, 0.0), Vec3::new(-1.0, 0.5, 0.3)] {
                let mut out = [Rgb::ZERO; 2];
                let terms = tree.gather(x, 2, &eval, &mut out);
                let mut exact = [0.0f64; 2];
                for (p, w) in pts.iter().zip(&pw) {
                    let r = p.distance(x);
                    exact[0] += w.x as f64 * (-r as f64).exp();
                    exact[1] += w.x as f64 * (-0.3 * r as f64).exp();
                }
                for k in 0..2 {
                    let rel = (out[k].x as f64 - exact[k]).abs() / exact[k];
                    println!("theta {theta} x {x} k {k}: rel {rel:.2e}, {terms} terms");
                    assert!(rel < tol, "{x} k={k}: {rel}");
                }
                assert!(terms < pts.len() / 2, "{terms} terms");
            }
        }
    }
}
