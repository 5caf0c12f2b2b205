//! The finish of a bake whose tiles arrive as sample sums instead of being traced on the
//! way: a farm's merge (each tile summed from the parts' files) and each pass of a
//! progressive bake (each tile folded from the sums it kept in memory). Both hand their
//! tiles, in the canonical tree's sums ([`super::tile_sums`]), to the one-pass bake's
//! streaming finish ([`super::stream::finish_streaming`]), so there is one finish for all
//! three and the same samples give the same stack, bit for bit.

use super::band::{apron_rows, default_band_rows};
use super::stream::finish_streaming;
use super::tile_sums::TileSums;
use super::tiles::Tile;
use super::traced_tile::{rect_of, traced_from_sums, TracedTile};
use crate::bake::finish::describe::layer_report;
use crate::bake::prepare::context::BakeContext;
use crate::bake::report::BakeReport;
use crate::bake::settings::BakeSettings;
use crate::progress::{Progress, Stage};
use crate::scene::Scene;
use crate::stack::tiled::TiledStack;
use crate::Result;

/// What finishing summed tiles made: the stack, the report of its layers (timing, ray and
/// validation fields are the caller's), and its image at the bake-time materials when asked.
pub(crate) struct SummedFinish {
    pub stack: TiledStack,
    pub report: BakeReport,
    pub image: Option<Vec<f64>>,
}

/// Finishes a stack of `settings.spp` eye samples per pixel from `tile_sums`, which is asked
/// for each tile in raster order and returns its canonical sums (the right fold of its
/// blocks, [`super::tile_sums::TileBlocks::fold`]). The tiles are averaged and finished in
/// bands of tile rows as the one-pass bake finishes its traced ones, so what is held is the
/// stack, the bands in flight and whatever the caller keeps; `keep_image` adds the whole
/// bake-time image (one image, for a progressive bake's error estimate).
#[allow(clippy::too_many_arguments)]
pub(crate) fn finish_summed_tiles(
    ctx: &BakeContext,
    scene: &Scene,
    settings: &BakeSettings,
    pool: &rayon::ThreadPool,
    progress: &Progress,
    keep_image: bool,
    mut tile_sums: impl FnMut(&Tile) -> Result<TileSums>,
) -> Result<SummedFinish> {
    let spp = settings.spp;
    let rows = pool.install(|| {
        default_band_rows(
            ctx.resolution.width,
            settings.threads,
            apron_rows(&settings.denoise),
        )
    });
    let mut streamed = finish_streaming(
        ctx,
        scene,
        settings,
        rows,
        pool,
        progress,
        keep_image,
        |band_tiles| {
            band_tiles
                .iter()
                .map(|tile| {
                    progress.check()?;
                    let sums = tile_sums(tile)?;
                    traced_from_sums(rect_of(tile), sums.features, &sums.layers, spp)
                })
                .collect::<Result<Vec<TracedTile>>>()
        },
    )?;
    progress.set_stage(Stage::Finishing);
    let image = streamed.finished.image.take();
    let (stack, mut report) = layer_report(
        ctx,
        streamed.finished,
        streamed.assembly_seconds,
        streamed.denoise_seconds,
    );
    report.peak_accounted_bytes = streamed.peak_accounted_bytes;
    Ok(SummedFinish {
        stack,
        report,
        image,
    })
}
