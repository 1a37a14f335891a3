//! Raw bytes into the `.hyb` reader: it must return a model or an error, never panic,
//! hang or allocate absurdly; a model it returns must write and read back unchanged.
#![no_main]

use fabric_runtime::hybrid::format;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(model) = format::read(data) {
        let bytes = format::to_bytes(&model).expect("a model the reader accepts is valid, so it writes");
        assert_eq!(format::read(&bytes).expect("what the writer writes reads back"), model);
    }
});
