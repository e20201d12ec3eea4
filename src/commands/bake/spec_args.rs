//! The spec `bake`'s arguments ask for: receivers, transfer, storage, container, probes, and
//! what local lights compute.

use super::*;

/// What `bake`'s arguments ask of the bake of `mesh` (whose kind decides the container).
pub(crate) fn bake_spec(args: &BakeArgs, mesh: &Option<PathBuf>) -> Result<BakeSpec> {
    // Checked even where the bands are fixed: a nonsense option is refused, not ignored.
    spec::check_bands_threshold(args.bands_threshold)?;
    let defaults = BakeSpec::default();
    let options = args.transfer.options();
    let local = options.mode == bake::Mode::Local;
    Ok(BakeSpec {
        receivers: ReceiverSpec {
            fit: args.fit,
            fit_points: args.fit_points,
            lightmap: args.lightmap,
            lightmap_uv: args.lightmap_uv,
            denoise: args.denoise,
        },
        transfer: TransferSpec {
            bands: match args.transfer.bands {
                Bands::Fixed(bands) => spec::Bands::Fixed(bands),
                Bands::Auto => spec::Bands::Auto {
                    threshold: args.bands_threshold,
                },
            },
            samples: options.samples,
            sampling: options.sampling,
            seed: args.seed,
            mode: options.mode,
            albedo: args.albedo.map(|albedo| albedo.to_array()),
            bounces: args.bounces,
            bounce_tolerance: args.bounce_tolerance,
            target_error: args.target_error.map(|relative| TargetError {
                relative,
                max_samples: args.max_samples,
            }),
            subsurface: subsurface_material(args)?,
            materials_scatter: args.subsurface.as_deref() != Some("none"),
        },
        storage: StorageSpec {
            channels: args.storage,
            precision: args.precision,
            layout: args.compress.map_or(Layout::PerVertex, Layout::Cpca),
            zonal: zonal_spec(args)?,
        },
        // A glTF scene baked for local lights is a mesh to them: their file holds no scene.
        container: match mesh {
            Some(path) if scene::is_gltf(path) && !local => Container::GltfInPlace,
            _ => Container::Mesh,
        },
        local: local.then(|| local_options(args)),
        probes: probe_spec(args)?,
        ..defaults
    })
}

/// What `--mode local` computes: the gather's rays, the depth maps and the operator.
fn local_options(args: &BakeArgs) -> LocalOptions {
    let local = &args.local;
    LocalOptions {
        samples: args
            .transfer
            .samples
            .unwrap_or(LocalOptions::default().samples),
        seed: args.seed,
        bounces: args.bounces,
        grid_side: local.depth_grid,
        depth_clusters: local.depth_compress.0,
        depth_components: local.depth_compress.1,
        operator: OperatorShape {
            clusters: local.operator_compress.0,
            components: local.operator_compress.1,
            sparsity: local.sparsity,
            seed: args.seed,
        },
        example_lights: local.example_lights,
    }
}

/// The medium `--subsurface` and the `--sss-*` options ask for.
fn subsurface_material(args: &BakeArgs) -> Result<Option<spec::SubsurfaceMaterial>> {
    use prt_gpu::bake::subsurface::PRESETS;
    let Some(name) = &args.subsurface else {
        let given = args.sss_absorption.is_some()
            || args.sss_scattering.is_some()
            || args.sss_ior.is_some()
            || args.sss_mm_per_unit.is_some();
        return match given {
            true => Err(Error::Options(
                "--sss-absorption, --sss-scattering, --sss-ior and --sss-mm-per-unit describe \
                 a medium; ask for subsurface scattering with --subsurface MEDIUM"
                    .into(),
            )),
            false => Ok(None),
        };
    };
    let names = || PRESETS.map(|(n, _)| n).join(", ");
    let mut material = match name.as_str() {
        "none" => {
            return match args.sss_absorption.is_some() || args.sss_scattering.is_some() {
                true => Err(Error::Options(
                    "--subsurface none bakes every material opaque; --sss-absorption and \
                     --sss-scattering describe a medium"
                        .into(),
                )),
                false => Ok(None),
            }
        }
        "custom" => match (args.sss_absorption, args.sss_scattering) {
            (Some(_), Some(_)) => spec::SubsurfaceMaterial {
                ior: 1.3,
                absorption: [0.0; 3],
                reduced_scattering: [0.0; 3],
                mm_per_unit: 1000.0,
            },
            _ => {
                return Err(Error::Options(
                    "--subsurface custom needs --sss-absorption and --sss-scattering".into(),
                ))
            }
        },
        name => spec::SubsurfaceMaterial::preset(name).ok_or_else(|| {
            Error::Options(format!(
                "--subsurface {name}: not a medium this tool knows ({}, custom, or none)",
                names()
            ))
        })?,
    };
    if let Some(absorption) = args.sss_absorption {
        material.absorption = absorption.to_array();
    }
    if let Some(scattering) = args.sss_scattering {
        material.reduced_scattering = scattering.to_array();
    }
    material.ior = args.sss_ior.unwrap_or(material.ior);
    material.mm_per_unit = args.sss_mm_per_unit.unwrap_or(material.mm_per_unit);
    Ok(Some(material))
}

/// The zonal transfer `--zonal` and `--zonal-axis` ask for.
fn zonal_spec(args: &BakeArgs) -> Result<Option<spec::ZonalSpec>> {
    match (args.zonal, args.zonal_axis) {
        (Some(bands), axis) => Ok(Some(spec::ZonalSpec {
            bands,
            axis: axis.unwrap_or(spec::ZonalAxis::Normal),
        })),
        (None, Some(axis)) => Err(Error::Options(format!(
            "--zonal-axis {} says what zonal transfer is about; ask for it with --zonal BANDS",
            axis.name()
        ))),
        (None, None) => Ok(None),
    }
}

/// The probes `--probes`, `--probe-points` and `--probe-form` ask for.
fn probe_spec(args: &BakeArgs) -> Result<Option<spec::ProbeSpec>> {
    let placement = match (args.probes, &args.probe_points) {
        (Some(spacing), _) => spec::ProbePlacement::Grid { spacing },
        (None, Some(path)) => spec::ProbePlacement::Points(prt_gpu::probes::read_points(path)?),
        (None, None) => {
            if let Some(form) = args.probe_form {
                return Err(Error::Options(format!(
                    "--probe-form {} says what probes store; ask for them with --probes SPACING \
                     or --probe-points FILE",
                    form.name()
                )));
            }
            return Ok(None);
        }
    };
    Ok(Some(spec::ProbeSpec {
        placement,
        form: args.probe_form.unwrap_or(spec::ProbeForm::Radiance),
    }))
}
