//! A glTF scene baked in place by a streamed bake (`bake --memory-limit`): the document and
//! every view but the transfer's are written first, as [`super::encode_scene_glb`] writes them;
//! the chunks of transfer, which come in the baked (prepared, Morton) order of vertices, wait in
//! a scratch file; at the end each primitive's transfer view is filled from it in the scene's
//! own vertex order, a block of vertices at a time. Zonal transfer, fitted a chunk at a time,
//! waits in a scratch file of its own and fills its views the same way. The bytes are the
//! whole bake's.

use std::ops::Range;
use std::path::Path;
use std::time::Instant;

use super::{encode_scene, put_plane, Bin, Holds, SceneWrite};
use crate::bake::spill::Spill;
use crate::bake::{BakeMetadata, BakedMesh, Transfer, TransferShape};
use crate::error::Result;
use crate::fs::{check_destination, AtomicFile};
use crate::glb::zonal::write_run;
use crate::glb::{check_finite_coeffs, glb_head, groups, Stored};
use crate::precision::Precision;
use crate::probes::ProbeSet;
use crate::scene::gltf::GltfScene;
use crate::scene::prepare::DROPPED;
use crate::scene::Scene;
use crate::zonal::{ZonalSpec, ZonalTransfer};

/// A scene file being written: [`SceneStream::put`] takes the transfer of the next run of
/// baked vertices, [`SceneStream::commit`] writes the transfer views and puts the file in place.
pub struct SceneStream<'m> {
    file: AtomicFile,
    /// Each reserved view's offset in the file, the scene vertices it holds and what of theirs.
    views: Vec<(u64, Range<usize>, Holds)>,
    vertex_map: &'m [u32],
    spill: Spill,
    /// The zonal transfer's shape (no vertices) and its chunks' fits, each baked vertex's
    /// lobes then its axis, when the file holds one.
    zonal: Option<(ZonalTransfer, Spill)>,
    /// Baked vertices put so far.
    put: usize,
    shape: TransferShape,
    precision: Precision,
    /// Scene vertices per block when the views are filled.
    block: usize,
    report: SceneWrite,
    /// Seconds spent writing the file (not baking its chunks).
    seconds: f64,
}

impl<'m> SceneStream<'m> {
    /// Starts `gltf` baked in place at `path`, its transfer of the shape of `shape` (no
    /// coefficients) at `precision`, with `probes` and the zonal transfer `zonal` asks for;
    /// scene vertex `i` is baked vertex `vertex_map[i]`. The views are later filled `block`
    /// scene vertices at a time.
    pub fn create(
        path: &Path,
        gltf: &GltfScene,
        (shape, metadata): (TransferShape, &BakeMetadata),
        (precision, probes, zonal): (Precision, Option<&ProbeSet>, Option<ZonalSpec>),
        vertex_map: &'m [u32],
        block: usize,
    ) -> Result<SceneStream<'m>> {
        let started = Instant::now();
        check_destination(path)?;
        // The document names the transfer's attributes and reserves its views; it reads no
        // coefficient, so its mesh holds a transfer of the shape's bands and channels for no
        // receiver.
        let baked = BakedMesh {
            scene: Scene::default(),
            transfer: Transfer::zeros(shape.bands, shape.channels, 0),
            metadata: metadata.clone(),
            lightmap: None,
        };
        let streaming = Bin {
            streaming: true,
            ..Bin::default()
        };
        let zonal = zonal
            .map(|spec| {
                let bands = spec.bands.min(shape.bands);
                let shape = ZonalTransfer::new((bands, shape.channels, spec.axis), vec![], vec![])
                    .map_err(crate::error::Error::Options)?;
                Ok::<_, crate::error::Error>((shape, Spill::new()?))
            })
            .transpose()?;
        let stored = Stored::streamed(&baked, precision)
            .with_probes(probes)?
            .with_zonal(zonal.as_ref().map(|(shape, _)| shape))?;
        let (json, bin, report) = encode_scene(gltf, stored, vertex_map, None, streaming)?;
        let bin_len = bin.len().next_multiple_of(4);
        let head = glb_head(json, bin_len)?;
        let mut file = AtomicFile::create(path)?;
        file.set_len((head.len() + bin_len) as u64)?;
        file.write_at(0, &head)?;
        file.write_at(head.len() as u64, &bin.bytes)?;
        let start = head.len() as u64;
        Ok(SceneStream {
            file,
            views: bin
                .reserved
                .into_iter()
                .map(|(offset, vertices, holds)| (start + offset as u64, vertices, holds))
                .collect(),
            vertex_map,
            spill: Spill::new()?,
            zonal,
            put: 0,
            shape,
            precision,
            block: block.max(1),
            report,
            seconds: started.elapsed().as_secs_f64(),
        })
    }

    /// Takes the transfer of the baked vertices `first..first + chunk.vertex_count`, the next
    /// ones in order.
    pub fn put(&mut self, first: usize, chunk: &Transfer) -> Result<()> {
        assert_eq!(first, self.put, "chunks come in order");
        assert_eq!(
            (chunk.bands(), chunk.channels()),
            (self.shape.bands, self.shape.channels)
        );
        check_finite_coeffs(chunk, first)?;
        self.spill.append(chunk.coeffs())?;
        self.put += chunk.vertex_count();
        Ok(())
    }

    /// Takes the zonal fit of the baked vertices `first..first + chunk.vertex_count`, the
    /// ones [`SceneStream::put`] took last.
    pub fn put_zonal(&mut self, first: usize, chunk: &ZonalTransfer) -> Result<()> {
        let (_, spill) = self
            .zonal
            .as_mut()
            .expect("room reserved for zonal transfer");
        assert_eq!(
            first + chunk.vertex_count(),
            self.put,
            "in the order of the chunks"
        );
        let per_vertex = (chunk.channels() * chunk.bands()) as usize;
        let mut rows = Vec::with_capacity(chunk.vertex_count() * (per_vertex + 3));
        let lobes = chunk.coeffs().chunks_exact(per_vertex);
        for (lobe, axis) in lobes.zip(chunk.axes()) {
            rows.extend_from_slice(lobe);
            rows.extend(axis.to_array());
        }
        spill.append(&rows)?;
        Ok(())
    }

    /// Fills every reserved view from the scratch files and puts the file in place: what it
    /// wrote, and the seconds writing took.
    pub fn commit(mut self) -> Result<(SceneWrite, f64)> {
        let started = Instant::now();
        let (channels, groups) = (self.shape.channels as usize, groups(self.shape.bands));
        let per_vertex = channels * self.shape.coeffs_per_channel();
        let lanes = 4 * self.precision.bytes();
        for (at, vertices, holds) in std::mem::take(&mut self.views) {
            for start in vertices.clone().step_by(self.block) {
                let end = (start + self.block).min(vertices.end);
                let into = |offset: usize| at + offset as u64;
                if let Holds::Zonal(view) = holds {
                    let zonal = self.read_zonal_block(start..end)?;
                    let run = (vertices.len(), start - vertices.start);
                    let file = &mut self.file;
                    write_run(&zonal, view, run, &mut |offset, bytes| {
                        file.write_at(into(offset), bytes)
                    })?;
                    continue;
                }
                let (block, map) = self.read_block(start..end, per_vertex)?;
                for channel in 0..channels {
                    for group in 0..groups {
                        let mut bytes = Vec::with_capacity(lanes * map.len());
                        put_plane(&mut bytes, &block, &map, (channel, group), self.precision);
                        let plane = (channel * groups + group) * vertices.len();
                        let offset = lanes * (plane + start - vertices.start);
                        self.file.write_at(into(offset), &bytes)?;
                    }
                }
            }
        }
        self.file.commit()?;
        Ok((self.report, self.seconds + started.elapsed().as_secs_f64()))
    }

    /// The zonal fit at the scene vertices `vertices`, read from its scratch file, as the whole
    /// bake selects it (`ZonalTransfer::select`: a dropped vertex has no lobe, about z).
    fn read_zonal_block(&mut self, vertices: Range<usize>) -> Result<ZonalTransfer> {
        let (shape, spill) = self.zonal.as_mut().expect("zonal views reserved");
        let per_vertex = (shape.channels() * shape.bands()) as usize;
        let mut coeffs = vec![0.0f32; vertices.len() * per_vertex];
        let mut axes = vec![glam::Vec3::Z; vertices.len()];
        let mut row = vec![0.0f32; per_vertex + 3];
        for (k, &vertex) in self.vertex_map[vertices].iter().enumerate() {
            if vertex == DROPPED {
                continue;
            }
            spill.read_at((vertex as usize * row.len() * 4) as u64, &mut row)?;
            coeffs[k * per_vertex..(k + 1) * per_vertex].copy_from_slice(&row[..per_vertex]);
            axes[k] = glam::Vec3::from_slice(&row[per_vertex..]);
        }
        let shape = (shape.bands(), shape.channels(), shape.axis());
        Ok(ZonalTransfer::new(shape, axes, coeffs).expect("the fitted rows as they were spilled"))
    }

    /// The transfer of the scene vertices `vertices`, read from the scratch file, and their
    /// map into it (dropped vertices stay dropped).
    fn read_block(
        &mut self,
        vertices: Range<usize>,
        per_vertex: usize,
    ) -> Result<(Transfer, Vec<u32>)> {
        let mut coeffs = vec![0.0f32; vertices.len() * per_vertex];
        let mut map = Vec::with_capacity(vertices.len());
        for (k, &vertex) in self.vertex_map[vertices].iter().enumerate() {
            if vertex == DROPPED {
                map.push(DROPPED);
                continue;
            }
            let row = &mut coeffs[k * per_vertex..(k + 1) * per_vertex];
            let at = (vertex as usize * per_vertex * 4) as u64;
            self.spill.read_at(at, row)?;
            map.push(k as u32);
        }
        let (bands, channels) = (self.shape.bands, self.shape.channels);
        let block = Transfer::new(bands, channels, map.len(), coeffs)
            .expect("a row of coefficients for every vertex of the block");
        Ok((block, map))
    }
}
