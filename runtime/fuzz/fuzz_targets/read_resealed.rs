//! The same, after recomputing every checksum the input's own header and table point at:
//! random bytes almost never carry valid CRCs, so this target is what reaches the
//! semantic checks (ranges, indices, linked lists) behind them, as a hostile file would.
#![no_main]

use fabric_runtime::hybrid::format::{self, HEADER_SIZE, SECTION_ENTRY_SIZE, SectionEntry};
use libfuzzer_sys::fuzz_target;

/// Rewrites the section CRCs, the table CRC and the header CRC where they lie in bounds.
fn reseal(data: &[u8]) -> Vec<u8> {
    let mut b = data.to_vec();
    if b.len() < HEADER_SIZE {
        return b;
    }
    let u32_at = |b: &[u8], o: usize| u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
    let table = u64::from_le_bytes(b[24..32].try_into().unwrap_or([0; 8])) as usize;
    let count = (u32_at(&b, 32) as usize).min(4096);
    let size = SECTION_ENTRY_SIZE;
    if table >= HEADER_SIZE && table.checked_add(count * size).is_some_and(|end| end <= b.len()) {
        for k in 0..count {
            let at = table + k * size;
            let mut e = SectionEntry::from_bytes(&b[at..at + size]);
            let end = e.offset.checked_add(e.length);
            if let Some(end) = end.filter(|&end| end <= b.len() as u64) {
                e.crc32 = crc32fast::hash(&b[e.offset as usize..end as usize]);
                b[at..at + size].copy_from_slice(&e.to_bytes());
            }
        }
        let crc = crc32fast::hash(&b[table..table + count * size]);
        b[48..52].copy_from_slice(&crc.to_le_bytes());
    }
    let len = b.len() as u64;
    b[16..24].copy_from_slice(&len.to_le_bytes());
    b[44..48].fill(0);
    let crc = crc32fast::hash(&b[..HEADER_SIZE]);
    b[44..48].copy_from_slice(&crc.to_le_bytes());
    b
}

fuzz_target!(|data: &[u8]| {
    let bytes = reseal(data);
    if let Ok(model) = format::read(&bytes) {
        let again = format::to_bytes(&model).expect("a model the reader accepts is valid, so it writes");
        assert_eq!(format::read(&again).expect("what the writer writes reads back"), model);
    }
});
