//! What a bake prints: a line per stage that ran, and the summary line; for local lights, what
//! each of their stages made.

use super::*;

/// What the stages after the transfer did: the bands chosen, where compression ran, what it
/// made.
pub(super) fn print_shaping_lines(baked: &pipeline::Baked) {
    if let Some(chosen) = &baked.bands_chosen {
        eprintln!("{chosen}");
    }
    for note in &baked.notes {
        eprintln!("note: {note}");
    }
    if let Some(compressed) = &baked.compressed {
        eprintln!("{compressed}");
    }
    if let (Some(stored), Some(pass)) = (&baked.mesh.metadata.subsurface, &baked.report.subsurface)
    {
        eprintln!(
            "subsurface: {}; light followed {:.4} scene units under the surface (all but {} \
             of its reflectance), {} matrix entries a channel, built in {:.2} s",
            stored.describe(),
            pass.reach,
            prt_gpu::bake::subsurface::TAIL,
            pass.entries,
            pass.seconds
        );
    }
    if let Some((_, fit)) = &baked.zonal {
        eprintln!("{fit}");
    }
    print_probes_line(baked.probes.as_ref(), baked.probe_seconds);
}

/// The probes a bake made, if it made any.
pub(super) fn print_probes_line(probes: Option<&prt_gpu::probes::ProbeSet>, seconds: f64) {
    if let Some(probes) = probes {
        eprintln!(
            "probes: {}; {} rays each, in {seconds:.2} s",
            probes.describe(),
            probes.samples,
        );
    }
}

/// What baking a glTF scene in place did.
pub(super) fn print_in_place_report(
    written: &glb::scene::SceneWrite,
    seconds_load: f64,
    seconds_write: f64,
) {
    for repair in &written.repaired {
        eprintln!("warning: {repair}");
    }
    eprintln!(
        "baked in place: {} primitive(s), read in {seconds_load:.2} s, written in \
         {seconds_write:.2} s{}",
        written.primitives_baked,
        match written.mesh_copies {
            0 => String::new(),
            n => format!(
                "; {n} mesh(es) shown by several nodes copied, one per placement \
                 (each place sees its own occlusion)"
            ),
        }
    );
}

/// The parts a bake was merged from: how many, and the backend they ran on.
pub(super) type MergedFrom = Option<(u32, String)>;

/// One line for each stage that ran besides the direct pass: bounces, gather matrix, fit,
/// error target, lightmap (written beside `output`).
pub(super) fn print_stage_lines(report: &BakeReport, output: &Path) {
    for (i, bounce) in report.bounces.iter().enumerate() {
        let fit = match bounce.fit_iterations {
            Some(iterations) => format!(" (its fit solved in {iterations} iterations)"),
            None => String::new(),
        };
        eprintln!(
            "bounce {}: +{:.2}% energy in {:.2} s{fit}",
            i + 1,
            100.0 * bounce.relative_energy,
            bounce.seconds
        );
    }
    if report.gather_entries > 0 {
        // Each entry is a u32 column and an f32 weight.
        eprintln!(
            "gather matrix: {} entries ({:.1} MiB)",
            report.gather_entries,
            (report.gather_entries * 8) as f64 / (1u64 << 20) as f64
        );
    }
    if let Some(fit) = &report.fit {
        eprintln!(
            "least-squares fit: {} surface points, solved in {:.2} s ({} iterations, residual \
             {:.1e}, {} matrix entries)",
            report.receivers,
            report.seconds_fit,
            fit.iterations,
            fit.relative_residual,
            fit.matrix_entries
        );
    }
    if let Some(adaptive) = &report.adaptive {
        eprintln!(
            "target error: samples per receiver {} / {} / {} (min / median / max, mean {:.0}), \
             {} at the cap; estimated error {:.2e} / {:.2e} / {:.2e} (median / 90% / max)",
            adaptive.samples_min,
            adaptive.samples_median,
            adaptive.samples_max,
            adaptive.samples_mean,
            adaptive.at_cap,
            adaptive.error_median,
            adaptive.error_p90,
            adaptive.error_max
        );
    }
    if let Some(texels) = &report.texels {
        eprintln!(
            "lightmap: {}x{} texels, {} charts ({} seam edges), {} covered ({:.1}% of the \
             atlas; stretch {:.3}; {} inside geometry, refilled){}{}, {} rays in {:.2} s ({:.2} \
             M rays/s), {:.2} s in all -> {}",
            texels.width,
            texels.height,
            texels.charts,
            texels.seams,
            texels.covered,
            100.0 * texels.covered as f64 / (texels.width as f64 * texels.height as f64),
            texels.stretch,
            texels.leaking,
            if texels.denoised { ", denoised" } else { "" },
            texels.fit_points.map_or(String::new(), |points| format!(
                ", fitted to {points} points (least squares)"
            )),
            texels.rays_cast,
            texels.transfer_seconds,
            texels.rays_cast as f64 / texels.transfer_seconds.max(1e-9) / 1e6,
            texels.seconds,
            output
                .with_file_name(glb::lightmap_file_name(output))
                .display()
        );
    }
}

/// A finished bake's report: what prepare repaired, a line per stage, the one summary line.
pub(super) fn print_bake_report(
    name: &str,
    spec: &BakeSpec,
    bands: u32,
    report: &BakeReport,
    output: &Path,
    merged_from: MergedFrom,
) {
    if let Some(repairs) = report.prepare.repairs() {
        eprintln!("warning: {name}: {repairs}");
    }
    print_stage_lines(report, output);
    let seconds_bounces: f64 = report.bounces.iter().map(|b| b.seconds).sum();
    let seconds_texels = report.texels.map_or(0.0, |t| t.seconds);
    let seconds = report.seconds_prepare
        + report.seconds_transfer
        + report.seconds_fit
        + seconds_bounces
        + seconds_texels;
    let rays_per_second = report.rays_cast as f64 / report.seconds_transfer.max(1e-9);
    let rays = match merged_from {
        None => format!(
            "{} rays in {:.2} s ({:.2} M rays/s)",
            report.rays_cast,
            report.seconds_transfer,
            rays_per_second / 1e6
        ),
        Some((parts, ran_on)) => format!(
            "{} rays in {parts} shards ({ran_on}), merged",
            report.rays_cast
        ),
    };
    println!(
        "baked {name}: {} vertices, {} triangles, {} bands, {} {} samples, {} mode; {rays}, \
         {:.2} s in all ({}) -> {}",
        report.prepare.vertices,
        report.prepare.triangles,
        bands,
        match &report.adaptive {
            Some(adaptive) => format!("{:.0} (mean)", adaptive.samples_mean),
            None => report.samples_used.to_string(),
        },
        spec.transfer.sampling.name(),
        spec.transfer.mode.name(),
        seconds,
        report.backend,
        output.display()
    );
}

pub(crate) fn note_samples_rounded(options: &BakeOptions) {
    if options.samples_used() != options.samples {
        let side = (options.samples_used() as f64).sqrt() as u32;
        eprintln!(
            "note: --samples {} is not a square; {} sampling uses {} ({side} x {side} strata)",
            options.samples,
            options.sampling.name(),
            options.samples_used()
        );
    }
}

/// What a local-lights bake of `name` to `output` did, and a note where its compressed depth
/// maps outweigh the maps.
pub(super) fn print_local_report(name: &str, baked: &pipeline::LocalBaked, output: &Path) {
    let report = &baked.report;
    let mb = |bytes: usize| bytes as f64 / 1e6;
    println!(
        "local lights: {} receivers, {} triangles; gather matrix {} entries ({:.2} s); depth maps \
         {:.2} s, compressed {:.1} -> {:.1} MB, depth error {:.2}% ({:.2} s); {} example lights \
         ({:.2} s); operator {:.1} MB, {:.0}% of terms kept, error {:.2}% against the \
         sparse bounces ({:.2} s)",
        report.receivers,
        report.triangles,
        report.gather_entries,
        report.seconds_gather,
        report.seconds_depth,
        mb(report.depth_bytes_uncompressed),
        mb(report.depth_bytes),
        100.0 * report.depth_error,
        report.seconds_depth_compress,
        report.example_lights,
        report.seconds_examples,
        mb(report.operator_bytes),
        100.0 * report.operator_kept,
        100.0 * report.operator_error,
        report.seconds_operator
    );
    println!(
        "baked {name} for local lights: {} rays, {:.2} s on {} -> {}",
        report.rays_cast,
        report.seconds(),
        report.backend,
        output.display()
    );
    if report.depth_bytes > report.depth_bytes_uncompressed {
        eprintln!("{}", depth_maps_note(report, &baked.bake.options));
    }
}

/// What to tell a user whose compressed depth maps take more than the maps: how many clusters
/// would take no more.
fn depth_maps_note(report: &local::LocalReport, options: &LocalOptions) -> String {
    let mb = |bytes: usize| bytes as f64 / 1e6;
    let (clusters, components) = (options.depth_clusters, options.depth_components);
    let cells = (options.grid_side * options.grid_side) as usize;
    let fewer =
        match local::depth_clusters_within_maps(report.receivers, cells, components as usize) {
            Some(fit) => format!("--depth-compress {fit}x{components} or fewer clusters take less"),
            None => "fewer components take less".to_string(),
        };
    format!(
        "note: the compressed depth maps take {:.1} MB, more than the {:.1} MB of the maps: \
         {} receivers are few for {clusters} clusters of {components} components ({fewer})",
        mb(report.depth_bytes),
        mb(report.depth_bytes_uncompressed),
        report.receivers
    )
}
