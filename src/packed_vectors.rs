//! Serde for the large `Vec<[f64; 3]>` fields of checkpointed state (positions,
//! velocities, the contact detection's reference positions): in a human-readable format
//! (the checkpoint's JSON) one base64 string of the values' little-endian bytes, 32
//! characters per vector; in any other format the plain sequence.
//!
//! Why: as JSON numbers the 2000-sphere run's positions and velocities were 100 MB of
//! decimal text per rank and checkpoint, formatted and parsed number by number (a 330 MB
//! checkpoint took 1.3 s to write; docs/BENCHMARKS.md, session 75). The bytes are the
//! values' own, so the round trip is exact for every f64, NaN payloads included.
//! Deserialisation also takes the plain sequence, so checkpoints written before (format
//! 2) still restore.

use serde::de::{Error, SeqAccess, Visitor};
use serde::{Deserializer, Serialize, Serializer};

const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
/// Bytes of one vector, and its characters (24 bytes are 8 groups of 3: never padded).
const VECTOR_BYTES: usize = 24;
const VECTOR_CHARS: usize = 32;

/// Serialises `v` (see the module docs).
pub fn serialize<S: Serializer>(v: &[[f64; 3]], s: S) -> Result<S::Ok, S::Error> {
    if s.is_human_readable() {
        s.serialize_str(&encode(v))
    } else {
        v.serialize(s)
    }
}

/// Deserialises what [`serialize`] wrote, or a plain sequence of vectors.
pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<[f64; 3]>, D::Error> {
    d.deserialize_any(PackedVectors)
}

struct PackedVectors;

impl<'de> Visitor<'de> for PackedVectors {
    type Value = Vec<[f64; 3]>;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a base64 string of little-endian f64 triples, or a sequence of triples")
    }

    fn visit_str<E: Error>(self, text: &str) -> Result<Self::Value, E> {
        decode(text).map_err(E::custom)
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
        let mut out = Vec::with_capacity(seq.size_hint().unwrap_or(0));
        while let Some(v) = seq.next_element::<[f64; 3]>()? {
            out.push(v);
        }
        Ok(out)
    }
}

/// The base64 text of `v`'s little-endian bytes.
pub fn encode(v: &[[f64; 3]]) -> String {
    let mut text = vec![0u8; v.len() * VECTOR_CHARS];
    let mut bytes = [0u8; VECTOR_BYTES];
    for (vector, chars) in v.iter().zip(text.chunks_exact_mut(VECTOR_CHARS)) {
        for (i, c) in vector.iter().enumerate() {
            bytes[8 * i..8 * i + 8].copy_from_slice(&c.to_le_bytes());
        }
        for (group, quad) in bytes.chunks_exact(3).zip(chars.chunks_exact_mut(4)) {
            let n = u32::from(group[0]) << 16 | u32::from(group[1]) << 8 | u32::from(group[2]);
            for (c, shift) in quad.iter_mut().zip([18, 12, 6, 0]) {
                *c = ALPHABET[(n >> shift & 63) as usize];
            }
        }
    }
    String::from_utf8(text).expect("base64 is ASCII")
}

/// The vectors whose bytes `text` encodes (what [`encode`] writes).
pub fn decode(text: &str) -> Result<Vec<[f64; 3]>, String> {
    let text = text.as_bytes();
    if !text.len().is_multiple_of(VECTOR_CHARS) {
        return Err(format!(
            "packed vectors: {} characters, not a multiple of {VECTOR_CHARS}",
            text.len()
        ));
    }
    let mut value_of = [u8::MAX; 256];
    for (k, &c) in ALPHABET.iter().enumerate() {
        value_of[c as usize] = k as u8;
    }
    let mut out = Vec::with_capacity(text.len() / VECTOR_CHARS);
    let mut bytes = [0u8; VECTOR_BYTES];
    for (k, chars) in text.chunks_exact(VECTOR_CHARS).enumerate() {
        for (group, quad) in bytes.chunks_exact_mut(3).zip(chars.chunks_exact(4)) {
            let mut n = 0u32;
            for &c in quad {
                let d = value_of[c as usize];
                if d == u8::MAX {
                    return Err(format!(
                        "packed vectors: vector {k} holds '{}', not a base64 character",
                        c.escape_ascii()
                    ));
                }
                n = n << 6 | u32::from(d);
            }
            group.copy_from_slice(&n.to_be_bytes()[1..]);
        }
        out.push(std::array::from_fn(|i| {
            f64::from_le_bytes(bytes[8 * i..8 * i + 8].try_into().expect("8 bytes"))
        }));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::{Deserialize, Serialize};

    #[derive(Debug, Serialize, Deserialize)]
    struct Holder {
        #[serde(with = "super")]
        x: Vec<[f64; 3]>,
    }

    fn bits(v: &[[f64; 3]]) -> Vec<u64> {
        v.iter().flatten().map(|c| c.to_bits()).collect()
    }

    /// Every f64 comes back with its bits through the JSON string: signed zeros,
    /// subnormals, infinities, NaNs with payloads and ordinary values of every exponent.
    #[test]
    fn every_f64_round_trips_to_the_bit_through_json() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        let special = [
            0.0,
            -0.0,
            f64::MIN_POSITIVE / 3.0,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::from_bits(0x7ff8_0000_dead_beef),
            f64::MAX,
            1.0e-3,
            -2.5e-9,
        ];
        let mut x: Vec<[f64; 3]> = special.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
        x.extend((0..1000).map(|_| [0; 3].map(|_| f64::from_bits(next()))));
        let json = serde_json::to_string(&Holder { x: x.clone() }).unwrap();
        assert_eq!(json.len(), r#"{"x":""}"#.len() + VECTOR_CHARS * x.len());
        let back: Holder = serde_json::from_str(&json).unwrap();
        assert_eq!(bits(&back.x), bits(&x));
        let empty = serde_json::to_string(&Holder { x: Vec::new() }).unwrap();
        assert_eq!(empty, r#"{"x":""}"#);
        assert!(serde_json::from_str::<Holder>(&empty).unwrap().x.is_empty());
    }

    /// The plain sequence that checkpoints of format 2 hold is read as well, and the
    /// encoding is standard base64 (a vector of known bytes).
    #[test]
    fn arrays_of_numbers_are_read_too_and_the_text_is_standard_base64() {
        let old = r#"{"x":[[1.5,-0.0,3e-7],[0.1,2.0,-4.25]]}"#;
        let h: Holder = serde_json::from_str(old).unwrap();
        assert_eq!(bits(&h.x), bits(&[[1.5, -0.0, 3e-7], [0.1, 2.0, -4.25]]));
        // 1.0 is 00 00 00 00 00 00 f0 3f little-endian; 0.0 is eight zero bytes
        assert_eq!(
            encode(&[[1.0, 0.0, 0.0]]),
            "AAAAAAAA8D8AAAAAAAAAAAAAAAAAAAAA"
        );
    }

    /// Damaged text is an error naming what is wrong, never a panic or a silent value.
    #[test]
    fn damaged_text_is_an_error() {
        let good = encode(&[[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        let short = &good[..good.len() - 1];
        assert!(decode(short).unwrap_err().contains("not a multiple of 32"));
        let mut bad = good.clone().into_bytes();
        bad[40] = b'*';
        let err = decode(std::str::from_utf8(&bad).unwrap()).unwrap_err();
        assert!(err.contains("vector 1") && err.contains("'*'"), "{err}");
        let json = format!(r#"{{"x":"{short}"}}"#);
        assert!(serde_json::from_str::<Holder>(&json).is_err());
    }
}
