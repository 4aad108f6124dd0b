//! `tilegraph`: the command-line face of the library. Thin: parsing, printing, files.

mod devices;
mod image_io;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "tilegraph",
    version,
    about = "Render graphs for tile-based GPUs, validated on lavapipe"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List every Vulkan device, its identity, the profile chosen and why, and the memory type
    /// chosen for each use.
    Devices {
        /// One JSON array instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// The demo: device discovery, then a rendered frame written as PNG.
    Demo {
        /// Where to write the frame.
        #[arg(long, default_value = "target/demo/frame.png")]
        out: PathBuf,
        /// Frame size, WxH.
        #[arg(long, default_value = "320x180", value_parser = parse_size)]
        size: (u32, u32),
    },
}

/// Errors of the CLI: each names what failed.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    #[error(transparent)]
    Vk(#[from] tilegraph_vk::VkError),
    #[error(transparent)]
    Profile(#[from] tilegraph_profile::ProfileError),
    #[error("writing {path}: {reason}")]
    Write { path: PathBuf, reason: String },
    #[error("JSON: {0}")]
    Json(#[from] serde_json::Error),
}

pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WxH, got {s:?}"))?;
    let w: u32 = w.trim().parse().map_err(|e| format!("width {w:?}: {e}"))?;
    let h: u32 = h.trim().parse().map_err(|e| format!("height {h:?}: {e}"))?;
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        return Err(format!("size {w}x{h} is outside 1..=16384"));
    }
    Ok((w, h))
}

fn main() -> ExitCode {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Devices { json } => devices::run(json),
        Command::Demo { out, size } => demo(&out, size),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("tilegraph: {e}");
            ExitCode::FAILURE
        }
    }
}

fn demo(out: &std::path::Path, (width, height): (u32, u32)) -> Result<(), CliError> {
    devices::run(false)?;
    let ctx = tilegraph_vk::Context::new(tilegraph_vk::ContextOptions::from_env())?;
    println!(
        "\nrendering on {:?} with profile {} ({})",
        ctx.physical.identity.device_name,
        ctx.profile().name,
        ctx.selection.matched_by
    );
    let img = tilegraph_vk::first_frame::render_triangle(&ctx, width, height)?;
    image_io::write_png(out, &img)?;
    ctx.check_validation()?;
    println!("wrote {} ({width}x{height})", out.display());
    Ok(())
}
