//! How stored floats are kept: float32, or IEEE half floats at half the bytes. Every writer of
//! half-float data (per-vertex transfer, compressed transfer) rounds through here, so what a
//! bake reports as its error is the error of the file.

/// How stored coefficients are kept.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    clap::ValueEnum,
    serde::Serialize,
    serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// float32.
    #[default]
    F32,
    /// IEEE half floats: half the bytes, relative rounding error at most 2^-11 for values in
    /// the normal range (magnitude at least 2^-14; smaller ones are kept to 2^-25 absolute).
    F16,
}

impl Precision {
    /// Bytes per stored value.
    pub fn bytes(self) -> usize {
        match self {
            Precision::F32 => 4,
            Precision::F16 => 2,
        }
    }

    /// `x` as stored at this precision and read back.
    pub fn round(self, x: f32) -> f32 {
        match self {
            Precision::F32 => x,
            Precision::F16 => half::f16::from_f32(x).to_f32(),
        }
    }

    /// Every value of `values` as stored and read back.
    pub fn round_all(self, values: &[f32]) -> Vec<f32> {
        values.iter().map(|&x| self.round(x)).collect()
    }

    /// `values` as little-endian bytes at this precision.
    pub fn encode(self, values: &[f32], bytes: &mut Vec<u8>) {
        match self {
            Precision::F32 => values.iter().for_each(|x| bytes.extend(x.to_le_bytes())),
            Precision::F16 => values
                .iter()
                .for_each(|&x| bytes.extend(half::f16::from_f32(x).to_le_bytes())),
        }
    }

    /// Little-endian `bytes` at this precision as floats (a trailing partial value is
    /// ignored; callers check lengths).
    pub fn decode(self, bytes: &[u8]) -> Vec<f32> {
        match self {
            Precision::F32 => bytes
                .chunks_exact(4)
                .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect(),
            Precision::F16 => bytes
                .chunks_exact(2)
                .map(|b| half::f16::from_le_bytes([b[0], b[1]]).to_f32())
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Precision;

    #[test]
    fn encoding_then_decoding_gives_the_rounded_values() {
        let values = [0.0f32, 1.0, -0.333_333_34, 65504.0, 1.0e-6, 3.0e-5, 0.1];
        for precision in [Precision::F32, Precision::F16] {
            let mut bytes = Vec::new();
            precision.encode(&values, &mut bytes);
            assert_eq!(bytes.len(), values.len() * precision.bytes());
            assert_eq!(precision.decode(&bytes), precision.round_all(&values));
        }
        assert_eq!(Precision::F32.round_all(&values), values);
    }

    #[test]
    fn half_rounding_stays_within_its_stated_bound() {
        for i in 0..10_000 {
            let x = (i as f32 * 0.618_034).sin() * 10f32.powi(i % 9 - 6);
            let error = (Precision::F16.round(x) - x).abs();
            let bound = if x.abs() >= 2f32.powi(-14) {
                x.abs() * 2f32.powi(-11)
            } else {
                2f32.powi(-25)
            };
            assert!(error <= bound, "{x}: error {error} over {bound}");
        }
        // Rounding is not the identity: the bound above is attained, not vacuous.
        assert_ne!(Precision::F16.round(0.1), 0.1);
    }
}
