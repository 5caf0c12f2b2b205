//! The per-pixel loops of every kernel implementation this CPU runs against the scalar ones
//! (`tile_output.rs`), bit for bit.

use super::kernels::tests::pseudo;
use super::kernels::{Kernels, Portable};
use super::tile_output::{ColumnHats, TileOutputKernels, MAX_COLUMNS};

fn hats(width: usize, nodes: usize, seed: u32) -> ColumnHats {
    let mut h = ColumnHats {
        width,
        ..Default::default()
    };
    for (x, w) in pseudo(width, seed).into_iter().enumerate() {
        let n0 = (x * (nodes - 1)) / width.max(1);
        h.node[0][x] = n0 as u32;
        h.node[1][x] = (n0 + 1).min(nodes - 1) as u32;
        h.weight[0][x] = w.abs() / 10.0;
        h.weight[1][x] = 1.0 - h.weight[0][x];
    }
    h
}

/// Both loops once: the row of nodes interpolated along x, and an image row (a pixel more
/// on each side, so a store outside it would show) from `offset` floats into its buffer.
fn run<K: TileOutputKernels>(
    k: K,
    reset: bool,
    width: usize,
    nodes: usize,
    offset: usize,
) -> (Vec<f32>, Vec<f32>) {
    let row = pseudo(nodes, 7 + nodes as u32);
    let h = hats(width, nodes, width as u32);
    let mut along = vec![-1.0; MAX_COLUMNS];
    k.along_x(&row, &h, &mut along);
    let (mut r, g, b) = (pseudo(width, 1), pseudo(width, 2), pseudo(width, 3));
    r[0] = -0.0;
    let mut image = pseudo(4 * (width + 2) + 1, 4);
    image[offset + 3] = -0.0;
    k.image_row(&mut image[offset..offset + 4 * width], &r, &g, &b, reset);
    k.end_of_band();
    (along, image)
}

/// Every implementation gives the scalar loops' results bit for bit, at every tile width
/// and row length, the image row 16-byte aligned (streamed when reset: the buffer comes
/// from the allocator, 16-byte aligned, and the row starts 4 floats in) or not (5 floats).
#[test]
fn every_implementation_equals_the_scalar_loops() {
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for k in Kernels::available() {
        for reset in [false, true] {
            for width in 1..=MAX_COLUMNS {
                for (nodes, offset) in (1..=10).flat_map(|n| [(n, 4), (n, 5)]) {
                    let want = run(Portable, reset, width, nodes, offset);
                    let got = match k {
                        Kernels::Portable => run(Portable, reset, width, nodes, offset),
                        #[cfg(target_arch = "x86_64")]
                        Kernels::Avx2(a) => run(a, reset, width, nodes, offset),
                        #[cfg(target_arch = "x86_64")]
                        Kernels::Avx512(a) => run(a, reset, width, nodes, offset),
                    };
                    let case = format!("{k:?}, reset {reset}, {width} px, {nodes} nodes");
                    assert_eq!(bits(&got.0), bits(&want.0), "along x: {case}");
                    assert_eq!(bits(&got.1), bits(&want.1), "image row: {case}");
                }
            }
        }
    }
}
