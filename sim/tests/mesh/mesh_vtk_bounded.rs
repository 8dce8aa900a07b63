//! Bounded memory: a VTK file whose header claims 10^12 points (or a zlib block that claims to
//! expand a few bytes to gigabytes) is refused with a clear error before anything is allocated
//! for the claim. A global allocator records the largest single allocation while each such
//! file is read: it must stay far below what the claim would need (the files are tiny).

use crate::mesh_text;
use crate::vtk_build;

use lop_sim::mesh::{read_mesh, read_surface};
use lop_test_support::alloc::largest_on_this_thread;
use mesh_text::*;
use vtk_build::*;

// The counting allocator (`Counting::armed_threads`) is installed once for this
// test binary, in `main.rs`.

const TRILLION: &str = "1000000000000";

/// Reads `bytes` as `name` (a surface if `surface`), expects an error naming the file and
/// saying each needle, and checks no allocation exceeded 64 KiB meanwhile (every reader
/// reserves no more records than the file could hold; the claims here need terabytes).
fn refused_small(dir: &std::path::Path, name: &str, bytes: &[u8], surface: bool, needles: &[&str]) {
    let path = write(dir, name, bytes);
    let (read, largest) = largest_on_this_thread(|| {
        if surface {
            read_surface(&path).map(|_| ())
        } else {
            read_mesh(&path).map(|_| ())
        }
    });
    let err = read.expect_err(name);
    let msg = err.to_string();
    println!("{msg} (largest allocation {largest} bytes)");
    assert!(msg.contains(name), "{msg}");
    for n in needles {
        assert!(msg.contains(n), "{n:?} missing from {msg}");
    }
    assert!(
        largest < 64 << 10,
        "{name}: an allocation of {largest} bytes"
    );
}

#[test]
fn headers_claiming_a_trillion_points_are_refused_before_allocating() {
    let dir = scratch("bounded");
    // VTK XML in every encoding: NumberOfPoints="10^12".
    for e in all_encodings() {
        let name = name(&e);
        let t = cube_vtu(&e);
        let t = String::from_utf8_lossy(&t).replace(
            "NumberOfPoints=\"8\"",
            &format!("NumberOfPoints=\"{TRILLION}\""),
        );
        // Raw appended data is not UTF-8 text: patch the bytes instead.
        let bytes = if e.place == Place::Raw {
            patch(
                &cube_vtu(&e),
                b"NumberOfPoints=\"8\"",
                format!("NumberOfPoints=\"{TRILLION}\"").as_bytes(),
            )
        } else {
            t.into_bytes()
        };
        refused_small(&dir, &name, &bytes, false, &[TRILLION]);
    }

    // Legacy VTK, ASCII and binary.
    let ascii = VTK.replace("POINTS 8 double", &format!("POINTS {TRILLION} double"));
    refused_small(&dir, "ascii.vtk", ascii.as_bytes(), false, &[TRILLION]);
    let mut bin = format!("# vtk DataFile Version 3.0\nx\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS {TRILLION} double\n").into_bytes();
    bin.extend([0u8; 64]);
    refused_small(
        &dir,
        "binary.vtk",
        &bin,
        false,
        &["24000000000000 bytes", "64 bytes left"],
    );
    let mut cells =
        b"# vtk DataFile Version 3.0\nx\nBINARY\nDATASET POLYDATA\nPOINTS 1 float\n".to_vec();
    cells.extend([0u8; 12]);
    cells.extend(format!("\nPOLYGONS {TRILLION} {TRILLION}\n").into_bytes());
    cells.extend([0u8; 16]);
    refused_small(
        &dir,
        "cells.vtk",
        &cells,
        true,
        &["4000000000000 bytes", "bytes left"],
    );

    // A zlib block that claims to expand 10 compressed bytes to 24 MB, consistent with
    // NumberOfPoints="1000000": refused by the deflate ratio before decompressing.
    let e = Encoding {
        place: Place::Raw,
        big: false,
        u64_header: false,
        zlib: Some(48),
        separate: true,
    };
    let mut b = patch(
        &cube_vtu(&e),
        b"NumberOfPoints=\"8\"",
        b"NumberOfPoints=\"1000000\"",
    );
    let start = b.windows(4).position(|w| w == b"   _").unwrap() + 4;
    for (k, v) in [1u32, 24_000_000, 0, 10].iter().enumerate() {
        b[start + 4 * k..start + 4 * k + 4].copy_from_slice(&v.to_le_bytes());
    }
    refused_small(
        &dir,
        "ratio.vtu",
        &b,
        false,
        &["10 compressed bytes declared to expand to 24000000"],
    );
}

fn patch(bytes: &[u8], from: &[u8], to: &[u8]) -> Vec<u8> {
    let at = bytes.windows(from.len()).position(|w| w == from).unwrap();
    let mut out = bytes[..at].to_vec();
    out.extend_from_slice(to);
    out.extend_from_slice(&bytes[at + from.len()..]);
    out
}
