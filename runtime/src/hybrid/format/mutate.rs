//! Random damage to a `.hyb` file's bytes, for the reader's mutation tests and
//! `fabric bench --stress`: bit flips, truncation, overwritten words and spliced copies —
//! what storage and transfer do to files. A reader must answer each with an error or,
//! where the damage was harmless (padding between sections), the original model.

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
