//! The `prt-gpu` command line: parse, call the library, report. No baking logic lives here.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// `println!` that ends quietly when the reader of stdout has gone (`prt-gpu bake | head -1`),
/// where the standard one panics: every report line of the CLI goes through it. The progress
/// bars step aside while it prints, so a line never lands inside a bar.
macro_rules! println {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let line = format!($($arg)*);
        $crate::commands::bars().suspend(|| {
            let _ = writeln!(std::io::stdout(), "{line}");
        });
    }};
}

/// `eprintln!` with the progress bars stepped aside, as [`println!`].
macro_rules! eprintln {
    ($($arg:tt)*) => {{
        let line = format!($($arg)*);
        $crate::commands::bars().suspend(|| std::eprintln!("{line}"));
    }};
}

mod commands;

use commands::*;

#[derive(Parser)]
#[command(
    name = "prt-gpu",
    version,
    about = "Precomputed radiance transfer baker"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Bake per-vertex SH transfer vectors for a mesh (the built-in scene when none is given).
    Bake(BakeArgs),
    /// Print the metadata of a baked file.
    Info {
        /// A .glb written by `prt-gpu bake`.
        file: PathBuf,
    },
    /// List the GPU adapters wgpu can see, best first.
    Devices,
    /// Project lighting onto SH: an environment map and/or analytic lights (they add up).
    Light(LightArgs),
    /// Relight baked files under a light and render them side by side to PNG or EXR.
    Render(RenderArgs),
    /// Write a self-contained web viewer (one HTML file, WebGL2) of baked files and a light.
    View(ViewArgs),
    /// Export a baked file for other run-times.
    #[command(subcommand)]
    Export(ExportCommand),
    /// Chart speed against accuracy: every sampling strategy and backend over a sweep of
    /// sample counts, against a high-sample reference bake (SVG or PNG, plus a CSV beside it).
    Chart(ChartArgs),
    /// Time the direct-transfer pass on the CPU and GPU backends side by side (rays/s).
    Bench(BenchArgs),
    /// Join the parts of a sharded bake (`bake … --shard I/N`) into the file the unsharded bake
    /// writes, byte for byte; bounces, fits and lightmaps run here.
    Merge(MergeArgs),
}

fn main() -> ExitCode {
    // Mesa's software drivers probe for a Wayland display and complain on stderr, once per
    // adapter, when XDG_RUNTIME_DIR is unset (typical of CI and containers). Give them one
    // before any thread exists.
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir());
    }
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) if !e.use_stderr() => e.exit(),
        Err(e) => {
            eprintln!("{}", usage_error_line(&e.to_string()));
            return ExitCode::from(2);
        }
    };
    let result = match cli.command {
        Command::Bake(args) => run_bake(args),
        Command::Info { file } => run_info(&file),
        Command::Devices => run_devices(),
        Command::Light(args) => run_light(args),
        Command::Render(args) => run_render(args),
        Command::View(args) => run_view(args),
        Command::Export(ExportCommand::X3d(args)) => run_export_x3d(args),
        Command::Chart(args) => run_chart(args),
        Command::Bench(args) => run_bench(args),
        Command::Merge(args) => run_merge(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error}");
            ExitCode::FAILURE
        }
    }
}

/// clap's multi-line usage error as one line: the error, and the possible values if listed.
fn usage_error_line(message: &str) -> String {
    let mut lines = message.lines().map(str::trim).filter(|l| !l.is_empty());
    let mut line = lines
        .next()
        .unwrap_or("error: invalid arguments")
        .to_string();
    if let Some(values) = lines.find(|l| l.starts_with("[possible values")) {
        line.push(' ');
        line.push_str(values);
    }
    line
}
