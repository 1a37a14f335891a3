//! Random damage to a `.hyb` file's bytes, for the reader's mutation tests and
//! `fabric bench --stress`: bit flips, truncation, overwritten words and spliced copies —
//! what storage and transfer do to files. A reader must answer each with an error or,
//! where the damage was harmless (padding between sections), the original model. The
//! other readers' fuzz tests (OBJ, EXR, PNG, `.vol`) use the same damage, plus
//! [`extreme_word`]: a header field set to a value that breaks arithmetic.

use crate::brdf::twin::SplitMix64;

/// The kinds of raw damage [`mutate`] does.
pub const KINDS: u64 = 4;

/// `good` damaged one way, chosen by `rng` (`kind` < [`KINDS`]).
pub fn mutate(good: &[u8], kind: u64, rng: &mut SplitMix64) -> Vec<u8> {
    let mut b = good.to_vec();
    let n = b.len().max(1) as u64;
    match kind % KINDS {
        0 => {
            for _ in 0..1 + rng.next_u64() % 4 {
                let at = (rng.next_u64() % n) as usize;
                if at < b.len() {
                    b[at] ^= 1 << (rng.next_u64() % 8);
                }
            }
        }
        1 => b.truncate((rng.next_u64() % n) as usize),
        2 => {
            let at = (rng.next_u64() % n) as usize;
            for (k, x) in rng.next_u64().to_le_bytes().iter().enumerate() {
                if at + k < b.len() {
                    b[at + k] = *x;
                }
            }
        }
        _ => {
            let (from, to) = ((rng.next_u64() % n) as usize, (rng.next_u64() % n) as usize);
            let from = from.min(b.len());
            let chunk: Vec<u8> = b[from..(from + (rng.next_u64() % 64) as usize).min(b.len())].to_vec();
            let to = to.min(b.len());
            b.splice(to..to, chunk);
        }
    }
    b
}

/// Values that break readers' arithmetic: zero, −1, the extremes of i32, NaN, ∞, 1e30,
/// and sizes just past common limits (as u32 or f32 bits, little-endian).
pub const EXTREME_WORDS: [u32; 10] = [0, 0xFFFF_FFFF, 0x7FFF_FFFF, 0x8000_0000, 0x7FC0_0000, 0x7F80_0000, 0x7149_F2CA, 65536, 1 << 20, 3];

/// `good` with one aligned 4-byte word among its first `within` bytes set to one of
/// [`EXTREME_WORDS`] (most header fields are aligned words); unchanged if too short.
pub fn extreme_word(good: &[u8], within: usize, rng: &mut SplitMix64) -> Vec<u8> {
    let mut b = good.to_vec();
    let words = within.min(b.len()) / 4;
    if words > 0 {
        let at = (rng.next_u64() % words as u64) as usize * 4;
        let v = EXTREME_WORDS[(rng.next_u64() % EXTREME_WORDS.len() as u64) as usize];
        b[at..at + 4].copy_from_slice(&v.to_le_bytes());
    }
    b
}

/// One damaged copy of `good` for a reader's fuzz test: one of the [`KINDS`] of
/// [`mutate`], or (as often as each) [`extreme_word`] among the first `header` bytes.
pub fn damage(good: &[u8], header: usize, rng: &mut SplitMix64) -> Vec<u8> {
    let kind = rng.next_u64() % (KINDS + 1);
    if kind < KINDS { mutate(good, kind, rng) } else { extreme_word(good, header, rng) }
}
