//! `mesobake explicit`: a mesh tile's triangles mapped through the shell into one OBJ or
//! binary glTF.

use super::output::{Progress, print_json};
use mesobake_bake::surface::explicit::ExplicitInput;
use mesobake_core::fs::write_atomic;
use mesobake_core::limits::Limits;
use mesobake_core::{Error, Result};
use mesobake_scene::explicit::explicit_input;
use std::path::PathBuf;
use std::time::Instant;

/// Options of `mesobake explicit`.
#[derive(clap::Args)]
pub struct ExplicitArgs {
    /// Base mesh OBJ (with UVs).
    #[arg(long, required_unless_present = "scene", conflicts_with = "scene")]
    mesh: Option<PathBuf>,
    /// Tile OBJ in tile units: x, y over the unit tile (repeating), z in [0, --tile-height].
    #[arg(long, required_unless_present = "scene", conflicts_with = "scene")]
    tile: Option<PathBuf>,
    /// A scene file instead: its base mesh, shell, and OBJ tile or built-in sample (on the
    /// scene's resolution, tile height Z/X).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Shell thickness in object units [default: the tile's edge length in object units
    /// × tile height, which keeps the tile's proportions].
    #[arg(long, conflicts_with = "scene")]
    thickness: Option<f64>,
    /// Tiles per UV unit along u and v, e.g. 24x10 [default: 1x1].
    #[arg(long, value_parser = parse_tiling, conflicts_with = "scene")]
    tiles: Option<[f64; 2]>,
    /// The tile's height H in tile units (Z/X of its grid) [default: 0.5].
    #[arg(long, conflicts_with = "scene")]
    tile_height: Option<f64>,
    /// Largest distance (object units) between an output edge's midpoint and the exact
    /// mapping of its texture midpoint [default: 1e-3 × thickness].
    #[arg(long)]
    tolerance: Option<f64>,
    /// Output mesh: binary glTF when it ends in `.glb`, OBJ otherwise.
    #[arg(long)]
    out: PathBuf,
    /// Print the statistics as JSON on stdout.
    #[arg(long)]
    json: bool,
}

/// Maps the tile through the shell and writes the OBJ.
pub fn explicit(args: ExplicitArgs, limits: &Limits) -> Result<()> {
    let ExplicitArgs {
        mesh,
        tile,
        scene,
        thickness,
        tiles,
        tile_height,
        tolerance,
        out,
        json,
    } = args;
    let input = match (&scene, &mesh, &tile) {
        (Some(scene), _, _) => explicit_input(scene, limits)?,
        (None, Some(mesh), Some(tile)) => ExplicitInput::from_files(
            mesh,
            tile,
            thickness,
            tiles.unwrap_or([1.0, 1.0]),
            tile_height.unwrap_or(0.5),
            limits,
        )?,
        _ => {
            return Err(Error::InvalidParameter(
                "explicit needs --scene, or --mesh and --tile".into(),
            ));
        }
    };
    eprintln!(
        "mapping {} tile triangles through the shell of {} base triangles",
        input.tile.triangles.len(),
        input.base.triangles.len()
    );
    let progress = Progress::new("mapping prisms");
    let (shell, explicit) = input.export(tolerance, false, limits, &progress)?;
    progress.finish();
    let s = &explicit.stats;
    let start = Instant::now();
    let comment = format!(
        "mesobake explicit: {} triangles, {} vertices; tolerance {:e} (object units), \
         largest measured edge deviation {:e}",
        s.triangles_out, s.vertices_out, s.tolerance, s.max_deviation
    );
    let is_glb = out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("glb"));
    let bytes = if is_glb {
        explicit.mesh.to_glb(&comment)
    } else {
        explicit.mesh.to_obj(&comment).into_bytes()
    };
    write_atomic(&out, &bytes)?;
    let write_s = start.elapsed().as_secs_f64();
    eprintln!(
        "wrote {}: {} triangles, {} vertices from {} tile triangles over {} prisms \
         ({} clipped) in {:.2} s; largest edge deviation {:.3e} (tolerance {:.3e})",
        out.display(),
        s.triangles_out,
        s.vertices_out,
        s.triangles_in,
        s.prisms,
        s.triangles_clipped,
        s.seconds,
        s.max_deviation,
        s.tolerance
    );
    if json {
        print_json(&serde_json::json!({
            "output": out,
            "thickness": input.shell.thickness,
            "tiles_per_uv": input.shell.tiles_per_uv,
            "tile_height": input.tile_height,
            "stats": s,
            "shell": shell.report,
            "seconds": {"export": s.seconds, "write": write_s},
        }));
    }
    Ok(())
}

/// Parses "AxB" (e.g. "24x10") into two positive finite numbers.
fn parse_tiling(text: &str) -> Result<[f64; 2]> {
    let bad =
        || Error::InvalidParameter(format!("{text:?} is not two positive numbers like 24x10"));
    let (a, b) = text.split_once(['x', 'X']).ok_or_else(bad)?;
    let parse = |s: &str| {
        s.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite() && *v > 0.0)
            .ok_or_else(bad)
    };
    Ok([parse(a)?, parse(b)?])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_tiling_reads_tilings() {
        assert_eq!(parse_tiling("24x10").unwrap(), [24.0, 10.0]);
        assert_eq!(parse_tiling("1.5X2").unwrap(), [1.5, 2.0]);
        for bad in ["24", "0x1", "ax2", "1x-2", "infx1"] {
            assert!(parse_tiling(bad).is_err(), "{bad}");
        }
    }
}
