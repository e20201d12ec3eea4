//! How a bake's transfer is stored: per vertex or as clusters (clustered PCA), float32 or
//! float16, with or without a lightmap. One value, checked where it is made, that every writer
//! (the baked mesh, the glTF scene in place) takes, so no writer re-checks a flag.

use super::*;
use crate::probes::ProbeSet;
use crate::zonal::ZonalTransfer;

/// A bake as a file stores it: its transfer at a precision, compressed or not (the compressed
/// form then replaces the per-vertex one), its lightmap beside.
#[derive(Clone, Copy)]
pub struct Stored<'a> {
    baked: &'a BakedMesh,
    /// The transfer's shape: the baked mesh's, or (compressed from a streamed bake's scratch
    /// file) the shape of a transfer no one held whole.
    shape: TransferShape,
    cpca: Option<&'a Cpca>,
    precision: Precision,
    probes: Option<&'a ProbeSet>,
    zonal: Option<&'a ZonalTransfer>,
}

impl<'a> Stored<'a> {
    /// `baked` stored at `precision`, compressed as `cpca` (which must be the compression of
    /// its transfer) when given. Refuses what no file holds: transfer that does not hold its
    /// vertices' coefficients or is not finite, a lightmap stored in half floats (its texels
    /// are half floats of their own) or compressed (its texels are stored whole). What the
    /// container asks of the mesh is the writer's to check (a baked mesh's vertices carry the
    /// transfer; a scene maps its own vertices onto it).
    pub fn new(
        baked: &'a BakedMesh,
        cpca: Option<&'a Cpca>,
        precision: Precision,
    ) -> Result<Stored<'a>> {
        check_finite_coeffs(&baked.transfer, 0)?;
        if baked.lightmap.is_some() && precision == Precision::F16 {
            return Err(Error::Options(
                "--precision f16 stores per-vertex or compressed transfer; lightmaps have their \
                 own storage"
                    .into(),
            ));
        }
        if let Some(cpca) = cpca {
            validate_cpca(baked, cpca).map_err(Error::Geometry)?;
        }
        Ok(Stored {
            baked,
            shape: baked.transfer.shape(),
            cpca,
            precision,
            probes: None,
            zonal: None,
        })
    }

    /// `baked` (its transfer the shape of the compressed one, for no vertex) stored as `cpca`
    /// at `precision`: a streamed bake's transfer, compressed from its scratch file. Refuses a
    /// compressed transfer of other bands, channels or vertices than the mesh.
    pub fn compressed(
        baked: &'a BakedMesh,
        cpca: &'a Cpca,
        precision: Precision,
    ) -> Result<Stored<'a>> {
        let shape = TransferShape {
            vertex_count: cpca.vertex_count(),
            ..baked.transfer.shape()
        };
        if (cpca.bands, cpca.channels) != (shape.bands, shape.channels) {
            return Err(Error::Geometry(format!(
                "the compressed transfer has {} bands and {} channels, the mesh {} and {}",
                cpca.bands, cpca.channels, shape.bands, shape.channels
            )));
        }
        let vertices = baked.scene.positions.len();
        if baked.transfer.vertex_count() != 0 || baked.lightmap.is_some() {
            return Err(Error::Geometry(
                "a compressed streamed bake's mesh carries no transfer of its own".into(),
            ));
        }
        if vertices != 0 && vertices != cpca.vertex_count() {
            return Err(Error::Geometry(format!(
                "compressed transfer of {} vertices for a mesh of {vertices}",
                cpca.vertex_count()
            )));
        }
        Ok(Stored {
            baked,
            shape,
            cpca: Some(cpca),
            precision,
            probes: None,
            zonal: None,
        })
    }

    /// `baked` per vertex in float32, as `bake` writes it by default.
    pub fn plain(baked: &'a BakedMesh) -> Result<Stored<'a>> {
        Stored::new(baked, None, Precision::F32)
    }

    /// A file whose coefficients come later, chunk by chunk (a streamed bake): `shape` has the
    /// transfer's bands and channels and no coefficients, which are checked as each chunk
    /// comes.
    pub(super) fn streamed(shape: &'a BakedMesh, precision: Precision) -> Stored<'a> {
        Stored {
            baked: shape,
            shape: shape.transfer.shape(),
            cpca: None,
            precision,
            probes: None,
            zonal: None,
        }
    }

    /// The same, with `probes` (from a bake of this mesh) in the file beside its transfer.
    pub fn with_probes(self, probes: Option<&'a ProbeSet>) -> Result<Stored<'a>> {
        if let Some(why) = probes.and_then(ProbeSet::broken) {
            return Err(Error::Geometry(why.into()));
        }
        Ok(Stored { probes, ..self })
    }

    /// The same, with `zonal` (fitted to this mesh's transfer) in the file beside it.
    pub fn with_zonal(self, zonal: Option<&'a ZonalTransfer>) -> Result<Stored<'a>> {
        if let Some(zonal) = zonal {
            let (vertices, channels) = (self.shape.vertex_count, self.shape.channels);
            if zonal.vertex_count() != vertices || zonal.channels() != channels {
                return Err(Error::Geometry(format!(
                    "zonal transfer of {} vertices and {} channels for a mesh of {vertices} \
                     and {channels}",
                    zonal.vertex_count(),
                    zonal.channels()
                )));
            }
        }
        Ok(Stored { zonal, ..self })
    }

    pub fn zonal(&self) -> Option<&'a ZonalTransfer> {
        self.zonal
    }

    pub fn probes(&self) -> Option<&'a ProbeSet> {
        self.probes
    }

    pub fn baked(&self) -> &'a BakedMesh {
        self.baked
    }

    /// The transfer's bands, channels and vertices.
    pub fn transfer_shape(&self) -> TransferShape {
        self.shape
    }

    pub fn cpca(&self) -> Option<&'a Cpca> {
        self.cpca
    }

    pub fn precision(&self) -> Precision {
        self.precision
    }
}
