//! Writes NumPy `.npy` files (format 1.0): `numpy.load` reads them as they are.

use crate::files::WriteError;
use crate::invalid;

/// Encodes a row-major `rows × cols` array of `f32` as `.npy` bytes (little-endian `<f4`).
pub fn encode_f32(data: &[f32], rows: usize, cols: usize) -> Result<Vec<u8>, WriteError> {
    encode_f32_shaped(data, &[rows, cols])
}

/// Encodes a row-major (C-order) array of `f32` of any `shape` as `.npy` bytes.
pub fn encode_f32_shaped(data: &[f32], shape: &[usize]) -> Result<Vec<u8>, WriteError> {
    let dims: Vec<String> = shape.iter().map(usize::to_string).collect();
    if data.len() != shape.iter().product::<usize>() {
        invalid!(
            "npy: {} values do not make a {} array",
            data.len(),
            dims.join("×")
        );
    }
    // A tuple of one needs its comma: (5,).
    let tuple = match dims.as_slice() {
        [one] => format!("({one},)"),
        _ => format!("({})", dims.join(", ")),
    };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {tuple}, }}");
    // Magic (6) + version (2) + length (2) + header + '\n' is padded to a multiple of 64.
    let total = 10 + header.len() + 1;
    header.push_str(&" ".repeat(total.next_multiple_of(64) - total));
    header.push('\n');
    let Ok(header_len) = u16::try_from(header.len()) else {
        invalid!(
            "npy: a {}-dimensional shape is too long for the header",
            shape.len()
        );
    };
    let mut out = Vec::with_capacity(10 + header.len() + 4 * data.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&header_len.to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_is_aligned_and_data_follows() {
        let bytes = encode_f32(&[1.0, 2.5, -3.0, 0.0, 4.0, 5.0], 2, 3).unwrap();
        assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
        let hlen = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        assert_eq!((10 + hlen) % 64, 0);
        let header = std::str::from_utf8(&bytes[10..10 + hlen]).unwrap();
        assert!(header.contains("'shape': (2, 3)") && header.ends_with('\n'));
        let data = &bytes[10 + hlen..];
        assert_eq!(data.len(), 24);
        assert_eq!(f32::from_le_bytes(data[4..8].try_into().unwrap()), 2.5);
        assert!(encode_f32(&[1.0], 2, 3).is_err());
        let cube = encode_f32_shaped(&[0.0; 12], &[2, 2, 3]).unwrap();
        assert!(String::from_utf8_lossy(&cube).contains("'shape': (2, 2, 3)"));
        let line = encode_f32_shaped(&[0.0; 5], &[5]).unwrap();
        assert!(String::from_utf8_lossy(&line).contains("'shape': (5,)"));
    }
}
