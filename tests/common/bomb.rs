//! A decompression bomb for the refusal tests of the CLI and the service.

/// A PNG that declares `w`x`h` pixels in its header and holds none: a decompression bomb.
pub fn png_bomb(w: u32, h: u32) -> Vec<u8> {
    fn crc32(data: &[u8]) -> u32 {
        let mut c = !0u32;
        for &b in data {
            c ^= b as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 { 0xedb8_8320 ^ (c >> 1) } else { c >> 1 };
            }
        }
        !c
    }
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    for (kind, body) in [(&b"IHDR"[..], [w.to_be_bytes(), h.to_be_bytes()].concat()), (&b"IDAT"[..], vec![])] {
        let mut chunk = kind.to_vec();
        chunk.extend(&body);
        if kind == b"IHDR" {
            chunk.extend([8, 2, 0, 0, 0]);
        }
        out.extend(((chunk.len() - 4) as u32).to_be_bytes());
        out.extend(&chunk);
        out.extend(crc32(&chunk).to_be_bytes());
    }
    out
}
