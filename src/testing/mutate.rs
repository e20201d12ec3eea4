//! Deterministic mutations of a file's bytes, the kind that break readers: flipped bits,
//! truncations, spans cut, copied or inserted, numbers in text swapped for huge, negative or
//! non-finite ones, JSON values swapped for values of another type, and 32-bit words set to
//! counts and offsets just past what the data holds. Seeded, so that a failure names a case
//! that can be run again.

/// A source of mutations: splitmix64 (Steele, Lea and Flood), enough for choosing bytes.
pub struct Mutator {
    state: u64,
}

/// Numbers written in place of a number of the text: edges of the integer types, counts past
/// any buffer, values that overflow f32, and spellings of NaN and infinity.
const NUMBERS: [&str; 16] = [
    "0",
    "-1",
    "3",
    "255",
    "65536",
    "2147483648",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "99999999999999999999",
    "1e39",
    "-1e39",
    "1e-45",
    "NaN",
    "inf",
    "0.5",
];

/// JSON values written in place of one of the text's values.
const JSON_VALUES: [&str; 9] = [
    "null",
    "\"x\"",
    "[]",
    "{}",
    "-1",
    "1e400",
    "true",
    "[0,1]",
    "4294967295",
];

/// 32-bit words written over the data at an aligned offset.
const WORDS: [u32; 10] = [
    0,
    1,
    0xFFFF,
    0x7FFF_FFFF,
    0x8000_0000,
    0xFFFF_FFFF,
    0x7F80_0000, // +infinity as f32
    0x7FC0_0000, // NaN as f32
    0xFF80_0000, // -infinity as f32
    0x0001_0000,
];

impl Mutator {
    pub fn new(seed: u64) -> Mutator {
        Mutator { state: seed }
    }

    fn next(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A number in `0..n` (0 when `n` is 0).
    pub fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.next() % n as u64) as usize
        }
    }

    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }

    /// `bytes` changed by one to three mutations, and their names joined by `+`.
    pub fn mutate(&mut self, bytes: &[u8]) -> (Vec<u8>, String) {
        let mut out = bytes.to_vec();
        let mut names = Vec::new();
        for _ in 0..1 + self.below(3) {
            names.push(self.mutate_once(&mut out));
        }
        (out, names.join("+"))
    }

    fn mutate_once(&mut self, bytes: &mut Vec<u8>) -> &'static str {
        let text = bytes.iter().filter(|b| b.is_ascii_digit()).count() > 0
            && bytes
                .iter()
                .take(64)
                .all(|b| !b.is_ascii_control() || b"\r\n\t".contains(b));
        match self.below(if text { 10 } else { 8 }) {
            0 => self.flip_bit(bytes),
            1 => self.set_byte(bytes),
            2 => self.truncate(bytes),
            3 => self.cut_span(bytes),
            4 => self.copy_span(bytes),
            5 => self.insert_bytes(bytes),
            6 | 7 => self.set_word(bytes),
            8 => self.swap_number(bytes),
            _ => self.swap_json_value(bytes),
        }
    }

    fn flip_bit(&mut self, bytes: &mut [u8]) -> &'static str {
        if !bytes.is_empty() {
            let at = self.below(bytes.len());
            bytes[at] ^= 1 << self.below(8);
        }
        "flip-bit"
    }

    fn set_byte(&mut self, bytes: &mut [u8]) -> &'static str {
        if !bytes.is_empty() {
            let at = self.below(bytes.len());
            bytes[at] = *self.pick(&[0u8, 0xFF, 0x7F, 0x80, b' ', b'\n', b'-', b'/', b'"']);
        }
        "set-byte"
    }

    fn truncate(&mut self, bytes: &mut Vec<u8>) -> &'static str {
        let at = self.below(bytes.len());
        bytes.truncate(at);
        "truncate"
    }

    fn span(&mut self, len: usize) -> (usize, usize) {
        let start = self.below(len);
        let end = start + 1 + self.below((len - start).min(64));
        (start, end.min(len))
    }

    fn cut_span(&mut self, bytes: &mut Vec<u8>) -> &'static str {
        if !bytes.is_empty() {
            let (start, end) = self.span(bytes.len());
            bytes.drain(start..end);
        }
        "cut-span"
    }

    fn copy_span(&mut self, bytes: &mut Vec<u8>) -> &'static str {
        if !bytes.is_empty() {
            let (start, end) = self.span(bytes.len());
            let copied = bytes[start..end].to_vec();
            let at = self.below(bytes.len() + 1);
            bytes.splice(at..at, copied);
        }
        "copy-span"
    }

    fn insert_bytes(&mut self, bytes: &mut Vec<u8>) -> &'static str {
        let at = self.below(bytes.len() + 1);
        let count = 1 + self.below(16);
        let inserted: Vec<u8> = (0..count).map(|_| self.next() as u8).collect();
        bytes.splice(at..at, inserted);
        "insert-bytes"
    }

    fn set_word(&mut self, bytes: &mut [u8]) -> &'static str {
        if bytes.len() >= 4 {
            let at = 4 * self.below(bytes.len() / 4);
            let word = match self.below(WORDS.len() + 2) {
                i if i < WORDS.len() => WORDS[i],
                // Sizes just past the data: the counts and offsets a reader must check.
                i if i == WORDS.len() => bytes.len() as u32,
                _ => bytes.len() as u32 + 1,
            };
            bytes[at..at + 4].copy_from_slice(&word.to_le_bytes());
        }
        "set-word"
    }

    /// Replaces a run of digits (with its sign, point and exponent) by one of [`NUMBERS`].
    fn swap_number(&mut self, bytes: &mut Vec<u8>) -> &'static str {
        let starts: Vec<usize> = (0..bytes.len())
            .filter(|&i| bytes[i].is_ascii_digit() && (i == 0 || !is_number_byte(bytes[i - 1])))
            .collect();
        if starts.is_empty() {
            return "swap-number";
        }
        let start = *self.pick(&starts);
        let end = start
            + bytes[start..]
                .iter()
                .position(|&b| !is_number_byte(b))
                .unwrap_or(bytes.len() - start);
        let start = if start > 0 && bytes[start - 1] == b'-' {
            start - 1
        } else {
            start
        };
        let number = self.pick(&NUMBERS).as_bytes().to_vec();
        bytes.splice(start..end, number);
        "swap-number"
    }

    /// Replaces the value after a `:` of JSON text (up to the next `,`, `}` or `]`, or a whole
    /// bracketed value) by one of [`JSON_VALUES`].
    fn swap_json_value(&mut self, bytes: &mut Vec<u8>) -> &'static str {
        let colons: Vec<usize> = (0..bytes.len()).filter(|&i| bytes[i] == b':').collect();
        if colons.is_empty() {
            return "swap-json-value";
        }
        let start = *self.pick(&colons) + 1;
        let end = value_end(bytes, start);
        let value = self.pick(&JSON_VALUES).as_bytes().to_vec();
        bytes.splice(start..end, value);
        "swap-json-value"
    }
}

fn is_number_byte(b: u8) -> bool {
    b.is_ascii_digit() || matches!(b, b'.' | b'e' | b'E' | b'+' | b'-')
}

/// Where the JSON value starting at `start` ends: after its closing bracket when it opens one
/// (strings skipped), otherwise at the next `,`, `}` or `]`.
fn value_end(bytes: &[u8], start: usize) -> usize {
    let mut depth = 0usize;
    let mut in_string = false;
    let mut i = start;
    while i < bytes.len() {
        let b = bytes[i];
        if in_string {
            match b {
                b'\\' => i += 1,
                b'"' => in_string = false,
                _ => {}
            }
        } else {
            match b {
                b'"' => in_string = true,
                b'[' | b'{' => depth += 1,
                b']' | b'}' if depth == 0 => return i,
                b']' | b'}' => {
                    depth -= 1;
                    if depth == 0 {
                        return i + 1;
                    }
                }
                b',' if depth == 0 => return i,
                _ => {}
            }
        }
        i += 1;
    }
    bytes.len()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_seed_gives_the_same_mutations() {
        let seed = b"v 1 2 3\nf 1 2 3\n";
        let run = |s| {
            let mut m = Mutator::new(s);
            (0..50).map(|_| m.mutate(seed)).collect::<Vec<_>>()
        };
        assert_eq!(run(7), run(7));
        assert_ne!(run(7), run(8));
    }

    #[test]
    fn a_json_value_is_replaced_whole() {
        let text = br#"{"a":[1,[2,3]],"b":4}"#;
        assert_eq!(value_end(text, 5), 14);
        assert_eq!(value_end(text, 19), 20);
    }

    #[test]
    fn every_operator_changes_something_over_many_draws() {
        let seed = br#"{"count": 12, "uri": "data:x"}"#.to_vec();
        let mut m = Mutator::new(1);
        let changed = (0..200).filter(|_| m.mutate(&seed).0 != seed).count();
        assert!(changed > 180, "{changed} of 200 changed the bytes");
    }
}
