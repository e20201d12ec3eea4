//! The `prt-gpu` command line: parse, call the library, report. No baking logic lives here.

#![cfg_attr(not(test), deny(clippy::unwrap_used))]

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

/// clap's multi-line usage error as one line: the error with the lines that belong to it (the
/// missing arguments, the possible values), or, where a command was left out, the commands
/// there are.
fn usage_error_line(message: &str) -> String {
    let mut lines = message.lines();
    let first = lines.next().unwrap_or_default().trim();
    if !first.starts_with("error:") {
        // clap shows the help where a subcommand is missing: say which ones there are.
        return missing_command_line(message);
    }
    let mut line = first.to_string();
    for detail in lines.map(str::trim).take_while(|l| !l.is_empty()) {
        line.push(' ');
        line.push_str(detail);
    }
    line
}

/// `error: prt-gpu export needs a command: x3d (see --help)`, from the help clap printed.
fn missing_command_line(help: &str) -> String {
    let usage = help
        .lines()
        .find_map(|l| l.trim().strip_prefix("Usage: "))
        .unwrap_or("prt-gpu");
    let command = usage.split(" <COMMAND>").next().unwrap_or(usage).trim();
    let commands: Vec<&str> = help
        .lines()
        .skip_while(|l| l.trim() != "Commands:")
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .filter_map(|l| l.split_whitespace().next())
        .filter(|&name| name != "help")
        .collect();
    format!(
        "error: {command} needs a command: {} (see {command} --help)",
        commands.join(", ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn clap_error(args: &[&str]) -> String {
        match Cli::try_parse_from(args) {
            Ok(_) => panic!("{args:?} parsed"),
            Err(error) => usage_error_line(&error.to_string()),
        }
    }

    #[test]
    fn usage_errors_are_one_line_that_names_what_is_missing_or_wrong() {
        assert_eq!(
            clap_error(&["prt-gpu"]),
            "error: prt-gpu needs a command: bake, info, devices, light, render, view, export, \
             chart, bench, merge (see prt-gpu --help)"
        );
        assert_eq!(
            clap_error(&["prt-gpu", "export"]),
            "error: prt-gpu export needs a command: x3d (see prt-gpu export --help)"
        );
        let missing = clap_error(&["prt-gpu", "render"]);
        assert!(
            missing.starts_with("error: the following required arguments were not provided: ")
                && missing.contains("<BAKED>"),
            "{missing}"
        );
        let wrong = clap_error(&["prt-gpu", "bake", "--mode", "sideways"]);
        assert!(
            wrong.contains("'sideways'") && wrong.contains("[possible values: "),
            "{wrong}"
        );
        for line in [missing, wrong] {
            assert!(!line.contains('\n'), "{line}");
        }
    }
}
