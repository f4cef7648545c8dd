//! Any file content handed to the flash decoder gives a status per page and at most one restored
//! state, never a panic; a restored state passes the learner's checks and restores a car node.
#![no_main]

use hil_mock::flash::{FILE_SIZE, HEADER_SIZE, PageStatus, decode_pages, image_problem};
use libfuzzer_sys::fuzz_target;
use protocol::car::{CarConfig, CarNode};

fuzz_target!(|data: &[u8]| {
    let _ = image_problem(data);
    // As it is, and as the pages of an image (the header's magic in front, cut or padded).
    let mut image = vec![0xFFu8; FILE_SIZE];
    let n = data.len().min(FILE_SIZE - HEADER_SIZE);
    image[HEADER_SIZE..HEADER_SIZE + n].copy_from_slice(&data[..n]);
    for bytes in [data, &image[..]] {
        let (pages, restored) = decode_pages(bytes);
        if let Some(r) = restored {
            assert_eq!(pages[r.page], PageStatus::Good(r.generation));
            CarNode::restore(CarConfig::DEFAULT, &r.state).expect("a good page restores");
        }
    }
});
