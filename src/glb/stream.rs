//! A baked file written a chunk of vertices at a time, for bakes too large to hold every
//! vertex's transfer in memory (`bake --memory-limit`). The JSON chunk, the mesh's views and
//! the size of the transfer view are known before any coefficient is: they are written first,
//! and each chunk's coefficients go to their places in the planar transfer view. The bytes are
//! those [`super::write_glb`] writes for the same bake.

use std::borrow::Cow;
use std::ops::Range;
use std::path::Path;
use std::time::Instant;

use super::scene::stream::SceneStream;
use super::scene::SceneWrite;
use super::zonal::{write_run, ZonalView};
use super::{
    array_view, check_finite_coeffs, encode_json, encode_mesh_views, glb_head, groups,
    planar_bytes, planar_view, put_planar_block, validate_shape, Precision, Shape, Target,
};
use crate::bake::adaptive::{AdaptiveReport, ReceiverErrors};
use crate::bake::spill::Spill;
use crate::bake::stream::{Interreflected, StreamedBake};
use crate::bake::{
    Backend, BakeMetadata, BakeReport, BandEnergy, Mode, Progress, Transfer, TransferShape,
};
use crate::compress::Rows;
use crate::error::{Error, Result};
use crate::fs::AtomicFile;
use crate::probes::ProbeSet;
use crate::scene::gltf::GltfScene;
use crate::sh::coeff_count;
use crate::zonal::{ZonalFit, ZonalSpec, ZonalTally, ZonalTransfer};

/// A .glb being written: everything but the transfer is in place; `GlbStream::put` fills in
/// the transfer of a run of vertices, `GlbStream::commit` puts the file in place.
pub struct GlbStream {
    file: AtomicFile,
    /// File offset of the transfer view.
    transfer_start: u64,
    vertices: usize,
    channels: u32,
    bands: u32,
    precision: Precision,
    /// File offsets of the zonal coefficients' view and of the fitted axes' view.
    zonal_at: Option<(u64, Option<u64>)>,
}

impl GlbStream {
    /// Starts the file at `path` for the mesh and transfer shape of `shape`, the transfer at
    /// `precision`, with `probes` and room for the zonal transfer `zonal` asks for after it (as
    /// [`super::write_glb`] places them).
    fn create(
        path: &Path,
        shape: Shape,
        precision: Precision,
        (probes, zonal): (Option<&ProbeSet>, Option<ZonalSpec>),
    ) -> Result<GlbStream> {
        validate_shape(shape)?;
        let transfer = shape.transfer;
        let v = shape.scene.positions.len();
        let mut bin = Vec::new();
        let mut views = encode_mesh_views(shape.scene, &mut bin);
        let transfer_len = planar_bytes(v, transfer.channels, transfer.bands, precision)
            .expect("validate_shape bounds the file's size");
        views.push(planar_view(bin.len(), transfer_len, precision));
        // Every view's length is a multiple of 4, so the probes start aligned after the
        // transfer; their own views are padded to 4 as the whole file pads them.
        let tail_start = bin.len() + transfer_len;
        let mut tail = Vec::new();
        let probes = probes.map(|set| {
            super::probes::encode(set, |bytes| {
                tail.resize(tail.len().next_multiple_of(4), 0);
                let start = tail_start + tail.len();
                tail.extend_from_slice(&bytes);
                views.push(array_view(start, bytes.len(), None, Target::ArrayBuffer));
                views.len() - 1
            })
        });
        // The zonal views are reserved, not written: the file is sized with zeros, and each
        // chunk's fit goes to its place.
        let mut reserved = tail.len();
        let mut zonal_starts = Vec::new();
        let zonal = zonal.map(|spec| {
            let shape = (spec.bands.min(transfer.bands), transfer.channels, spec.axis);
            super::zonal::reserve(shape, v, |len, stride| {
                reserved = reserved.next_multiple_of(4);
                zonal_starts.push(tail_start + reserved);
                views.push(array_view(
                    tail_start + reserved,
                    len,
                    stride,
                    Target::ArrayBuffer,
                ));
                reserved += len;
                views.len() - 1
            })
        });
        let bin_len = tail_start + reserved.next_multiple_of(4);
        let extras = super::encode::Extras {
            cpca: None,
            probes,
            zonal,
        };
        let json = encode_json(shape, None, extras, views, bin_len, precision)?;
        let head = glb_head(json, bin_len)?;
        let total = head.len() + bin_len;
        let mut file = AtomicFile::create(path)?;
        file.set_len(total as u64)?;
        file.write_at(0, &head)?;
        file.write_at(head.len() as u64, &bin)?;
        file.write_at((head.len() + tail_start) as u64, &tail)?;
        let in_file = |start: usize| (head.len() + start) as u64;
        Ok(GlbStream {
            file,
            transfer_start: (head.len() + bin.len()) as u64,
            vertices: v,
            channels: transfer.channels,
            bands: transfer.bands,
            precision,
            zonal_at: zonal_starts
                .first()
                .map(|&start| (in_file(start), zonal_starts.get(1).map(|&s| in_file(s)))),
        })
    }

    /// Writes the transfer of the vertices `first..first + chunk.vertex_count`.
    fn put(&mut self, first: usize, chunk: &Transfer) -> Result<()> {
        assert_eq!(
            (chunk.bands(), chunk.channels()),
            (self.bands, self.channels)
        );
        assert!(first + chunk.vertex_count() <= self.vertices);
        check_finite_coeffs(chunk, first)?;
        // One vertex's four lanes of a block.
        let lanes = 4 * self.precision.bytes();
        let mut block = Vec::with_capacity(lanes * chunk.vertex_count());
        for channel in 0..self.channels as usize {
            for group in 0..groups(self.bands) {
                block.clear();
                put_planar_block(&mut block, chunk, channel, group, self.precision);
                let index = channel * groups(self.bands) + group;
                let at = self.transfer_start + (lanes * (index * self.vertices + first)) as u64;
                self.file.write_at(at, &block)?;
            }
        }
        Ok(())
    }

    /// Writes the zonal transfer of the vertices `first..first + chunk.vertex_count`.
    fn put_zonal(&mut self, first: usize, chunk: &ZonalTransfer) -> Result<()> {
        let (coefficients, axes) = self.zonal_at.expect("room reserved for zonal transfer");
        assert!(first + chunk.vertex_count() <= self.vertices);
        let views = [
            (ZonalView::Coefficients, Some(coefficients)),
            (ZonalView::Axes, axes),
        ];
        for (view, start) in views {
            if let Some(start) = start {
                let at = (self.vertices, first);
                let file = &mut self.file;
                write_run(chunk, view, at, &mut |offset, bytes| {
                    file.write_at(start + offset as u64, bytes)
                })?;
            }
        }
        Ok(())
    }

    fn commit(self) -> Result<()> {
        self.file.commit()
    }
}

/// Where a streamed bake goes: its file at `path`, the transfer at `precision`, and `each_chunk`,
/// which sees every chunk's transfer (in vertex order) before it is written, as the stages that
/// report on the whole transfer would.
pub struct StreamSink<'a> {
    pub path: &'a Path,
    /// The glTF scene the bake writes in place, or `None` for a baked mesh.
    pub scene: Option<&'a GltfScene>,
    pub precision: Precision,
    /// `--bands auto`'s threshold: the file keeps the fewest bands that leave less than it of
    /// the energy above them.
    pub bands_auto: Option<f64>,
    pub each_chunk: &'a mut dyn FnMut(&Transfer) -> Result<()>,
    /// Bakes the probes the file holds, once the transfer is known and before the file
    /// starts: given an interreflected bake's transfer (to read its exit light from) and the
    /// bands the file keeps.
    pub probes: Option<&'a mut ProbeStage<'a>>,
    /// The zonal transfer the file holds beside the SH transfer, fitted a chunk at a time (a
    /// baked mesh only).
    pub zonal: Option<ZonalSpec>,
    /// Whether the file stores the transfer compressed: then no file is started, and the
    /// chunks wait in a scratch file ([`StreamedWrite::held`]) for clustered PCA to read.
    pub compressed: bool,
}

/// What bakes a streamed file's probes ([`StreamSink::probes`]).
pub type ProbeStage<'a> = dyn FnMut(Option<&mut Interreflected>, u32) -> Result<ProbeSet> + 'a;

/// The file a streamed bake writes: a baked mesh, its chunks written in place as they come,
/// or a glTF scene, whose transfer views are filled at the end in the scene's vertex order.
enum Streaming<'m> {
    Mesh(GlbStream),
    Scene(SceneStream<'m>),
}

impl<'m> Streaming<'m> {
    /// Starts the file of `bake` with `metadata` where `sink` says; a scene's views are filled
    /// `chunk` scene vertices at a time.
    fn create(
        bake: &StreamedBake,
        (metadata, probes): (&BakeMetadata, Option<&ProbeSet>),
        sink: &StreamSink,
        vertex_map: &'m [u32],
        chunk: usize,
    ) -> Result<Streaming<'m>> {
        let (bands, channels) = (metadata.bands, metadata.channels);
        let shape_transfer = TransferShape {
            bands,
            channels,
            vertex_count: bake.scene().vertex_count(),
        };
        Ok(match sink.scene {
            None => {
                let shape = Shape {
                    scene: bake.scene(),
                    transfer: shape_transfer,
                    metadata,
                    lightmap: None,
                };
                let stored = (probes, sink.zonal);
                Streaming::Mesh(GlbStream::create(sink.path, shape, sink.precision, stored)?)
            }
            Some(gltf) => Streaming::Scene(SceneStream::create(
                sink.path,
                gltf,
                (shape_transfer, metadata),
                (sink.precision, probes, sink.zonal),
                vertex_map,
                chunk,
            )?),
        })
    }

    fn put(&mut self, first: usize, chunk: &Transfer) -> Result<()> {
        match self {
            Streaming::Mesh(file) => file.put(first, chunk),
            Streaming::Scene(file) => file.put(first, chunk),
        }
    }

    fn put_zonal(&mut self, first: usize, chunk: &ZonalTransfer) -> Result<()> {
        match self {
            Streaming::Mesh(file) => file.put_zonal(first, chunk),
            Streaming::Scene(file) => file.put_zonal(first, chunk),
        }
    }

    fn commit(self) -> Result<Option<(SceneWrite, f64)>> {
        match self {
            Streaming::Mesh(file) => file.commit().map(|()| None),
            Streaming::Scene(file) => file.commit().map(Some),
        }
    }
}

/// Bakes `bake` to its sink `chunk` receivers at a time on `backend`: at no time is more than
/// one chunk's transfer in memory. The file's bytes equal the whole bake's; a scene written in
/// place says what it wrote, and the seconds writing it took.
pub fn bake_streamed(
    bake: &StreamedBake,
    backend: &dyn Backend,
    chunk: usize,
    mut sink: StreamSink,
    progress: &dyn Progress,
) -> Result<StreamedWrite> {
    let started = Instant::now();
    let receivers = bake.receivers();
    let (interreflected, mut metadata) = begin(bake, backend, chunk, progress)?;
    let ranges: Vec<Range<usize>> = (0..receivers)
        .step_by(chunk)
        .map(|first| first..(first + chunk).min(receivers))
        .collect();
    let mut source = ChunkSource::new(bake, (backend, progress), interreflected);
    let target = bake.target_error();
    // --bands auto: the bands are known once every chunk is baked, and the file's layout
    // depends on them; an error target: the file records the mean samples of all receivers;
    // compressed, the clustering reads every chunk many times. The chunks then wait in a
    // scratch file (at the most bands).
    let hold = sink.bands_auto.is_some() || target.is_some() || sink.compressed;
    let mut held = match hold {
        true => Some(HeldChunks::bake(
            &ranges,
            &mut |range| source.next(range, metadata.channels),
            &metadata,
            sink.bands_auto,
        )?),
        false => None,
    };
    if let Some(held) = &held {
        metadata.bands = held.bands;
    }
    let adaptive = target.map(|target| AdaptiveReport::of(&source.adaptive, &target));
    if let Some(adaptive) = &adaptive {
        metadata.samples = adaptive.samples_mean.round() as u32;
    }
    let (probes, probe_seconds) =
        probe_stage(&mut sink, source.interreflected.as_mut(), metadata.bands)?;
    let (_, vertex_map, _) = bake.prepared();
    let recorded = (&metadata, probes.as_ref());
    let mut file = match sink.compressed {
        false => Some(Streaming::create(bake, recorded, &sink, vertex_map, chunk)?),
        true => None,
    };
    let mut zonal = sink.zonal.map(ZonalTally::new);
    let channels = metadata.channels;
    let zonal_held = pass_chunks(
        ranges,
        &mut |range| match &mut held {
            Some(held) => held.read(range, channels),
            None => source.next(range, channels),
        },
        &mut *sink.each_chunk,
        &mut file,
        (
            zonal.as_mut(),
            bake.scene().normals.as_deref().unwrap_or_default(),
        ),
    )?;
    let written = file.map(Streaming::commit).transpose()?.flatten();
    let seconds = started.elapsed().as_secs_f64();
    let bands_chosen = held
        .as_ref()
        .filter(|_| sink.bands_auto.is_some())
        .map(|held| (held.bands, held.beyond));
    let held = held.filter(|_| sink.compressed).map(|chunks| HeldTransfer {
        chunks,
        channels: metadata.channels,
        block: chunk,
        vertices: receivers,
        buffer: Vec::new(),
        metadata: metadata.clone(),
        zonal: zonal_held,
    });
    Ok(StreamedWrite {
        report: BakeReport {
            adaptive,
            ..streamed_report(
                bake,
                backend,
                (source.rays_cast, seconds),
                source.interreflected,
            )
        },
        scene_write: written,
        bands_chosen,
        probes,
        probe_seconds,
        zonal: zonal.and_then(|tally| tally.measured()),
        held,
    })
}

/// Checks `chunk` and runs what must finish before the first chunk: an interreflected bake's
/// bounces (the file records how many ran, and each bounce reads every vertex's last). The
/// bounces, and the metadata the file records.
fn begin(
    bake: &StreamedBake,
    backend: &dyn Backend,
    chunk: usize,
    progress: &dyn Progress,
) -> Result<(Option<Interreflected>, BakeMetadata)> {
    let receivers = bake.receivers();
    if chunk == 0 || receivers != bake.scene().vertex_count() {
        return Err(Error::Options(format!(
            "a streamed bake needs chunks of at least one receiver, one per vertex ({receivers} \
             receivers, {} vertices)",
            bake.scene().vertex_count()
        )));
    }
    let interreflected = match bake.mode() {
        Mode::Interreflected => Some(bake.interreflected(chunk, backend, progress)?),
        _ => None,
    };
    let bounces = interreflected.as_ref().map_or(0, |i| i.bounces.len());
    if interreflected.is_none() {
        progress.stage("transfer", receivers as u64);
    }
    Ok((interreflected, bake.metadata(backend, bounces)))
}

/// Passes the transfer of each of `ranges`, in order, from `next_chunk` to `each_chunk` and to
/// `file` (none where the file stores it compressed), fitting the zonal transfer as they come
/// (`zonal`, with every vertex's normal): the zonal transfer is given back where no file holds
/// it.
fn pass_chunks(
    ranges: Vec<Range<usize>>,
    next_chunk: &mut dyn FnMut(Range<usize>) -> Result<Transfer>,
    each_chunk: &mut dyn FnMut(&Transfer) -> Result<()>,
    file: &mut Option<Streaming>,
    (mut zonal, normals): (Option<&mut ZonalTally>, &[glam::Vec3]),
) -> Result<Option<ZonalTransfer>> {
    let mut zonal_held: Option<ZonalTransfer> = None;
    for range in ranges {
        let first = range.start;
        let transfer = next_chunk(range.clone())?;
        each_chunk(&transfer)?;
        if let Some(file) = file {
            file.put(first, &transfer)?;
        }
        if let Some(tally) = &mut zonal {
            let normals = normals.get(range).unwrap_or_default();
            let fitted = tally.fit(&transfer, normals)?;
            match (&mut *file, &mut zonal_held) {
                (Some(file), _) => file.put_zonal(first, &fitted)?,
                (None, Some(so_far)) => so_far.append(fitted),
                (None, None) => zonal_held = Some(fitted),
            }
        }
    }
    Ok(zonal_held)
}

/// The probes the sink asks for, baked once the transfer is known (`interreflected`: a bake's
/// scratch file to read the exit light from) at the file's `bands`, and their seconds.
fn probe_stage(
    sink: &mut StreamSink,
    interreflected: Option<&mut Interreflected>,
    bands: u32,
) -> Result<(Option<ProbeSet>, f64)> {
    let started = Instant::now();
    let probes = match sink.probes.as_mut() {
        Some(bake_probes) => Some(bake_probes(interreflected, bands)?),
        None => None,
    };
    Ok((probes, started.elapsed().as_secs_f64()))
}

/// Where a streamed bake's chunks come from: an interreflected bake's scratch file, or the
/// backend, a chunk of receivers at a time (tallying rays and, with an error target, each
/// receiver's samples and error).
struct ChunkSource<'b> {
    bake: &'b StreamedBake,
    backend: &'b dyn Backend,
    progress: &'b dyn Progress,
    interreflected: Option<Interreflected>,
    rays_cast: u64,
    adaptive: ReceiverErrors,
}

impl<'b> ChunkSource<'b> {
    /// Chunks of `bake` baked on `backend`, or read from its `interreflected` scratch file,
    /// whose direct pass is done: its receivers' samples and errors with it.
    fn new(
        bake: &'b StreamedBake,
        (backend, progress): (&'b dyn Backend, &'b dyn Progress),
        mut interreflected: Option<Interreflected>,
    ) -> Self {
        let adaptive = interreflected
            .as_mut()
            .and_then(|baked| baked.adaptive.take());
        ChunkSource {
            bake,
            backend,
            progress,
            interreflected,
            rays_cast: 0,
            adaptive: adaptive.unwrap_or_default(),
        }
    }

    /// The transfer of the receivers `range`, `channels` of it.
    fn next(&mut self, range: Range<usize>, channels: u32) -> Result<Transfer> {
        match &mut self.interreflected {
            Some(baked) => baked.chunk(range, channels),
            None => {
                let (transfer, rays, receivers) =
                    self.bake.chunk(range, self.backend, self.progress)?;
                self.rays_cast += rays;
                self.adaptive.extend(receivers.unwrap_or_default());
                Ok(transfer)
            }
        }
    }
}

/// The report of a streamed bake that cast `rays_cast` rays (its bounces' own count instead
/// where it is `interreflected`) in `seconds`.
fn streamed_report(
    bake: &StreamedBake,
    backend: &dyn Backend,
    (mut rays_cast, seconds): (u64, f64),
    interreflected: Option<Interreflected>,
) -> BakeReport {
    let (bounce_stats, gather_entries) = match interreflected {
        Some(baked) => {
            rays_cast = baked.rays_cast;
            (baked.bounces, baked.gather_entries)
        }
        None => (Vec::new(), 0),
    };
    let (prepare, vertex_map, seconds_prepare) = bake.prepared();
    BakeReport {
        prepare: prepare.clone(),
        vertex_map: vertex_map.clone(),
        receivers: bake.receivers(),
        samples_used: bake.samples_used() as u32,
        rays_cast,
        bvh_nodes: bake.bvh_nodes(),
        seconds_prepare,
        seconds_transfer: seconds,
        seconds_fit: 0.0,
        fit: None,
        texels: None,
        adaptive: None,
        bounces: bounce_stats,
        gather_entries,
        backend: backend.describe(),
        subsurface: None,
    }
}

/// A streamed bake's chunks at the most bands in a scratch file, and the bands `--bands auto`
/// keeps of them.
struct HeldChunks {
    spill: Spill,
    baked_bands: u32,
    bands: u32,
    /// The fraction of the energy in the bands left out.
    beyond: f64,
}

impl HeldChunks {
    /// Bakes the chunks `ranges` with `next_chunk`, summing each band's energy in vertex order
    /// as the whole bake does, and chooses the bands by `threshold` (keeps them all without).
    fn bake(
        ranges: &[Range<usize>],
        next_chunk: &mut dyn FnMut(Range<usize>) -> Result<Transfer>,
        metadata: &BakeMetadata,
        threshold: Option<f64>,
    ) -> Result<HeldChunks> {
        let mut spill = Spill::new()?;
        let mut energy = BandEnergy::new(metadata.bands);
        for range in ranges {
            let transfer = next_chunk(range.clone())?;
            energy.add(&transfer);
            spill.append(transfer.coeffs())?;
        }
        let (bands, beyond) = match threshold {
            Some(threshold) => energy.choose(threshold),
            None => (metadata.bands, 0.0),
        };
        Ok(HeldChunks {
            spill,
            baked_bands: metadata.bands,
            bands,
            beyond,
        })
    }

    /// The rows of the receivers `range` at the chosen bands, read into `buffer` (grown as
    /// needed, so that a reader of many chunks allocates once): how many floats they are.
    fn read_into(
        &mut self,
        range: Range<usize>,
        channels: u32,
        buffer: &mut Vec<f32>,
    ) -> Result<usize> {
        let (baked, kept) = (coeff_count(self.baked_bands), coeff_count(self.bands));
        let floats = range.len() * channels as usize * baked;
        if buffer.len() < floats {
            buffer.resize(floats, 0.0);
        }
        let at = (range.start * channels as usize * baked * 4) as u64;
        self.spill.read_at(at, &mut buffer[..floats])?;
        // Each channel's first `kept` coefficients moved forward in place: a destination
        // never lies after its source.
        if kept < baked {
            for segment in 0..range.len() * channels as usize {
                buffer.copy_within(segment * baked..segment * baked + kept, segment * kept);
            }
        }
        Ok(floats / baked * kept)
    }

    /// The chunk of the receivers `range` at the chosen bands.
    fn read(&mut self, range: Range<usize>, channels: u32) -> Result<Transfer> {
        let mut rows = Vec::new();
        let floats = self.read_into(range.clone(), channels, &mut rows)?;
        rows.truncate(floats);
        Ok(Transfer::new(self.bands, channels, range.len(), rows)
            .expect("the spilled chunk's rows"))
    }
}

/// What a streamed bake wrote.
pub struct StreamedWrite {
    pub report: BakeReport,
    /// What writing a glTF scene in place did, and its seconds.
    pub scene_write: Option<(SceneWrite, f64)>,
    /// With `--bands auto`: the bands kept and the fraction of the energy left above them.
    pub bands_chosen: Option<(u32, f64)>,
    /// The probes in the file, and the seconds they took.
    pub probes: Option<ProbeSet>,
    pub probe_seconds: f64,
    /// What the zonal transfer's fit cost, when the file holds one.
    pub zonal: Option<ZonalFit>,
    /// The transfer, where the sink stores it compressed and no file was written.
    pub held: Option<HeldTransfer>,
}

/// A streamed bake's transfer held in its scratch file, for clustered PCA to read a block of
/// chunks at a time ([`crate::compress::Rows`]), with what the file it becomes records.
pub struct HeldTransfer {
    chunks: HeldChunks,
    channels: u32,
    /// Rows a block: the bake's chunk.
    block: usize,
    vertices: usize,
    /// The last rows read, in place of a new allocation each read.
    buffer: Vec<f32>,
    pub metadata: BakeMetadata,
    /// The zonal transfer, fitted as the chunks came, where the file holds one.
    pub zonal: Option<ZonalTransfer>,
}

impl HeldTransfer {
    /// The transfer's bands (with `--bands auto`, those chosen) and channels.
    pub fn shape(&self) -> (u32, u32) {
        (self.chunks.bands, self.channels)
    }
}

impl Rows for HeldTransfer {
    fn dimension(&self) -> usize {
        self.channels as usize * coeff_count(self.chunks.bands)
    }

    fn len(&self) -> usize {
        self.vertices
    }

    fn block(&self) -> usize {
        self.block
    }

    fn read(&mut self, range: Range<usize>) -> Result<Cow<'_, [f32]>> {
        let floats = self
            .chunks
            .read_into(range, self.channels, &mut self.buffer)?;
        Ok(Cow::Borrowed(&self.buffer[..floats]))
    }
}
