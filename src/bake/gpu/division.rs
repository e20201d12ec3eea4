//! How the traversal kernels divide. Vulkan lets `/` be 2.5 ulps off, and an NVIDIA H200's is;
//! the CPU reference's is IEEE 754, so the kernels divide by `divide_rounded`
//! (wgsl/bvh.wgsl), an emulation of IEEE division that costs llvmpipe 1.4x the time of a bake.
//! An adapter whose own `/` rounds as IEEE's on every probe below (llvmpipe's does) is given
//! `/` instead, through the kernels' `DIVISION_IS_IEEE` override.

use super::*;

/// How the kernels divide: `/` where it was seen to round as IEEE 754, else the emulation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Division {
    Ieee,
    Emulated,
}

impl Division {
    /// Runs the arithmetic kernel with the adapter's own `/` on `probe_operands` and
    /// compares every quotient with the CPU's.
    pub fn probe(ctx: &GpuContext) -> Result<Division> {
        let operands = probe_operands();
        let results = arithmetic(ctx, &operands, Division::Ieee)?;
        let ieee = operands
            .iter()
            .zip(&results)
            .all(|(&[a, b], &[quotient, _])| {
                !ordinary(a, b) || quotient.to_bits() == (a / b).to_bits()
            });
        Ok(if ieee {
            Division::Ieee
        } else {
            Division::Emulated
        })
    }

    /// The kernels' pipeline constants.
    pub(super) fn constants(self) -> [(&'static str, f64); 1] {
        [("DIVISION_IS_IEEE", (self == Division::Ieee) as u8 as f64)]
    }
}

/// Operand pairs of every significand and a wide range of exponents (seeded), and the edges:
/// equal significands, the largest significand, quotients at the ends of the normal range,
/// zeros and subnormals.
pub(crate) fn probe_operands() -> Vec<[f32; 2]> {
    let mut rng = crate::sampling::Pcg32::new(29);
    let mut random = || {
        let exponent = 97 + rng.next_u32() % 60;
        let sign = rng.next_u32() & 0x8000_0000;
        f32::from_bits(sign | exponent << 23 | (rng.next_u32() & 0x7f_ffff))
    };
    let mut operands: Vec<[f32; 2]> = (0..20_000).map(|_| [random(), random()]).collect();
    let largest = f32::from_bits(0x3fff_ffff);
    let edges = [
        1.0,
        -1.0,
        3.0,
        0.1,
        largest,
        1e-20,
        -1e-20,
        1e20,
        f32::MAX,
        f32::MIN_POSITIVE,
        1e-40,
        0.0,
        -0.0,
        0.577_350_3,
    ];
    for a in edges {
        for b in edges.into_iter().filter(|&b| b != 0.0) {
            operands.push([a, b]);
        }
    }
    operands
}

/// Whether `a / b` is one the kernels must round as IEEE does: normal operands and a normal
/// quotient. (Elsewhere the hardware's `/` answers, and may flush to zero.)
pub(crate) fn ordinary(a: f32, b: f32) -> bool {
    a.is_normal() && b.is_normal() && (a / b).is_normal()
}

/// `(divide_rounded(a, b), rounded(a * b))` of every pair, on the adapter, dividing as
/// `division` says.
pub(crate) fn arithmetic(
    ctx: &GpuContext,
    operands: &[[f32; 2]],
    division: Division,
) -> Result<Vec<[f32; 2]>> {
    let pipeline = ctx.checked("compiling the arithmetic probe", || {
        pipeline_with(
            ctx,
            "arithmetic",
            shaders::arithmetic_kernel(),
            &division.constants(),
        )
    })?;
    // One triangle of the tree layout: three vec4 words, the last one's pad word 0.
    let triangles = ctx.storage("triangles", &[[0u32; 4]; 3]);
    let inputs = ctx.storage("operands", operands);
    let bytes = (operands.len() * 8) as u64;
    let results = ctx.output("results", bytes);
    let group = ctx.bind_buffers(
        "arithmetic",
        &pipeline.get_bind_group_layout(0),
        &[&triangles, &inputs, &results],
    );
    ctx.checked("running the arithmetic probe", || {
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        encode_pass(
            &mut encoder,
            "arithmetic",
            &pipeline,
            &group,
            [(operands.len() as u32).div_ceil(WORKGROUP_SIZE), 1, 1],
        );
        ctx.queue.submit([encoder.finish()]);
    })?;
    ctx.read_back(&results, bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The emulated division against the CPU's, bit for bit, on the adapter at hand; `rounded`
    /// leaves a product's bits as they are.
    #[test]
    fn the_emulated_division_rounds_as_the_cpu() {
        let Some(ctx) = crate::device::any_adapter_or_skip() else {
            return;
        };
        let operands = probe_operands();
        let results = arithmetic(&ctx, &operands, Division::Emulated).unwrap();
        let mut checked = 0;
        for (&[a, b], &[quotient, product]) in operands.iter().zip(&results) {
            if !ordinary(a, b) {
                continue;
            }
            checked += 1;
            let expected = a / b;
            assert_eq!(
                quotient.to_bits(),
                expected.to_bits(),
                "{a:e} / {b:e}: gpu {quotient:e}, cpu {expected:e}"
            );
            if (a * b).is_normal() {
                assert_eq!(product.to_bits(), (a * b).to_bits(), "{a:e} * {b:e}");
            }
        }
        assert!(checked > 19_000, "only {checked} quotients checked");
        // The probe agrees with itself: where it says IEEE, the plain kernels divide so.
        if Division::probe(&ctx).unwrap() == Division::Ieee {
            let plain = arithmetic(&ctx, &operands, Division::Ieee).unwrap();
            assert_eq!(plain, results);
        }
    }
}
