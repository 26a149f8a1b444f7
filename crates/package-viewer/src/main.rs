//! `mesobake-package-viewer PACKAGE OUT.png`: renders a depth view of a package's tiled
//! mesostructure on the GPU (see the library's documentation) and prints a JSON summary.

use clap::Parser;
use mesobake_package::Package;
use mesobake_package_viewer::{Viewer, shade};
use std::path::PathBuf;
use std::process::ExitCode;

/// Renders a depth view of a mesobake package's tiled mesostructure with wgpu.
#[derive(Parser)]
#[command(version)]
struct Args {
    /// The package (.mbpkg).
    package: PathBuf,
    /// The PNG to write.
    out: PathBuf,
    /// The view's direction bin a,b (default: the bin nearest 135° down, φ bin 0).
    #[arg(long, value_parser = parse_bin)]
    view: Option<(u32, u32)>,
    /// Copies of the tile along x and y.
    #[arg(long, default_value_t = 2)]
    tiles: u32,
    /// Use the adapter whose name contains this.
    #[arg(long)]
    adapter: Option<String>,
}

fn parse_bin(text: &str) -> Result<(u32, u32), String> {
    let (a, b) = text.split_once(',').ok_or("expected a,b")?;
    let bin = |s: &str| s.trim().parse::<u32>().map_err(|e| format!("{s:?}: {e}"));
    Ok((bin(a)?, bin(b)?))
}

fn run(args: Args) -> Result<serde_json::Value, String> {
    if !(1..=16).contains(&args.tiles) {
        return Err(format!("--tiles {}: expected 1 to 16", args.tiles));
    }
    let package = Package::read(&args.package, 1 << 32).map_err(|e| e.to_string())?;
    let (dims, dirs) = (package.dims(), package.dirs());
    let (a, b) = args.view.unwrap_or((dirs.n_theta * 3 / 4, 0));
    let viewer = Viewer::open(args.adapter.as_deref())?;
    let distances = viewer.top_layer(&package, a, b)?;
    let cos = dirs.theta(a).cos().abs() as f32;
    let (width, height) = (dims.x * args.tiles, dims.y * args.tiles);
    let mut rgb = Vec::with_capacity((width * height * 3) as usize);
    for y in 0..height {
        for x in 0..width {
            let texel = ((y % dims.y) * dims.x + x % dims.x) as usize;
            rgb.extend(shade(distances[texel], cos, dims.z));
        }
    }
    let file =
        std::fs::File::create(&args.out).map_err(|e| format!("{}: {e}", args.out.display()))?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
    writer.write_image_data(&rgb).map_err(|e| e.to_string())?;
    writer.finish().map_err(|e| e.to_string())?;
    Ok(serde_json::json!({
        "adapter": viewer.adapter,
        "codec": package.manifest().codec,
        "view": [a, b],
        "hits": distances.iter().filter(|d| d.is_some()).count(),
        "escapes": distances.iter().filter(|d| d.is_none()).count(),
        "image": [width, height],
    }))
}

fn main() -> ExitCode {
    match run(Args::parse()) {
        Ok(summary) => {
            println!("{summary}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
