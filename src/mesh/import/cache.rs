//! On-disk cache of meshed surface shapes, so a scene of many grains of a few distinct
//! shapes meshes quickly the second time. An entry is keyed by a text naming the mesher
//! version, the input file's length and hash, and every meshing option; it stores the key
//! itself (checked on load, so a hash collision of file names is harmless), the mesh
//! (f64 and u32, little-endian: bitwise the mesh that was made) and a checksum. A missing,
//! truncated, corrupted or mismatched entry is ignored and the shape re-meshed; entries are
//! written to a temporary file and renamed, so concurrent writers (MPI ranks) are safe.
//!
//! Location: `$MUFE_CACHE_DIR` (`off` disables the cache), else
//! `$XDG_CACHE_HOME/mufe/meshes`, else `$HOME/.cache/mufe/meshes`.

use std::path::{Path, PathBuf};

use crate::mesh::TetMesh;

const MAGIC: &[u8; 8] = b"MUFEMSH1";

/// The cache directory from the environment (`None`: caching off or no home).
pub fn cache_dir() -> Option<PathBuf> {
    if let Some(d) = std::env::var_os("MUFE_CACHE_DIR") {
        return (d != "off" && !d.is_empty()).then(|| PathBuf::from(d));
    }
    if let Some(x) = std::env::var_os("XDG_CACHE_HOME").filter(|x| !x.is_empty()) {
        return Some(PathBuf::from(x).join("mufe/meshes"));
    }
    std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/mufe/meshes"))
}

/// 64-bit FNV-1a.
pub fn fnv64(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

fn entry_path(dir: &Path, key: &str) -> PathBuf {
    dir.join(format!("{:016x}.mesh", fnv64(key.as_bytes())))
}

/// Whether an entry for `key` exists (not checked: [`load`] does that).
pub fn contains(dir: &Path, key: &str) -> bool {
    entry_path(dir, key).is_file()
}

/// The cached mesh for `key`, if a valid entry exists.
pub fn load(dir: &Path, key: &str) -> Option<TetMesh> {
    let bytes = std::fs::read(entry_path(dir, key)).ok()?;
    let body_len = bytes.len().checked_sub(8)?;
    let (body, sum) = bytes.split_at(body_len);
    if fnv64(body).to_le_bytes() != sum || !body.starts_with(MAGIC) {
        return None;
    }
    let mut at = MAGIC.len();
    let u64_at = |at: &mut usize| -> Option<u64> {
        let v = u64::from_le_bytes(body.get(*at..*at + 8)?.try_into().ok()?);
        *at += 8;
        Some(v)
    };
    let key_len = u64_at(&mut at)? as usize;
    if body.get(at..at.checked_add(key_len)?)? != key.as_bytes() {
        return None;
    }
    at += key_len;
    let (nn, nt) = (u64_at(&mut at)? as usize, u64_at(&mut at)? as usize);
    if body.len()
        != at
            .checked_add(nn.checked_mul(24)?)?
            .checked_add(nt.checked_mul(16)?)?
    {
        return None;
    }
    let f64s = |chunk: &[u8]| f64::from_le_bytes(chunk.try_into().unwrap_or([0; 8]));
    let nodes = body[at..at + 24 * nn]
        .chunks_exact(24)
        .map(|c| [f64s(&c[..8]), f64s(&c[8..16]), f64s(&c[16..])])
        .collect();
    at += 24 * nn;
    let tets = body[at..]
        .chunks_exact(16)
        .map(|c| {
            [0, 4, 8, 12].map(|k| u32::from_le_bytes(c[k..k + 4].try_into().unwrap_or([0; 4])))
        })
        .collect();
    let mesh = TetMesh { nodes, tets };
    crate::mesh::validate(&mesh).ok()?;
    Some(mesh)
}

/// Stores `mesh` under `key`; failures (read-only disk, no space) only lose the cache.
pub fn store(dir: &Path, key: &str, mesh: &TetMesh) {
    let mut out = Vec::with_capacity(64 + key.len() + 24 * mesh.nodes.len() + 16 * mesh.tets.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&(key.len() as u64).to_le_bytes());
    out.extend_from_slice(key.as_bytes());
    out.extend_from_slice(&(mesh.nodes.len() as u64).to_le_bytes());
    out.extend_from_slice(&(mesh.tets.len() as u64).to_le_bytes());
    for p in &mesh.nodes {
        for c in p {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    for t in &mesh.tets {
        for i in t {
            out.extend_from_slice(&i.to_le_bytes());
        }
    }
    let sum = fnv64(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    let path = entry_path(dir, key);
    let tmp = path.with_extension(format!("tmp{}", std::process::id()));
    let written = std::fs::create_dir_all(dir)
        .and_then(|()| std::fs::write(&tmp, &out))
        .and_then(|()| std::fs::rename(&tmp, &path));
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_corruption() {
        let dir = std::env::temp_dir().join(format!("mufe_cache_unit_{}", std::process::id()));
        let mesh = TetMesh {
            nodes: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            tets: vec![[0, 1, 2, 3]],
        };
        assert!(load(&dir, "k").is_none());
        store(&dir, "k", &mesh);
        assert_eq!(load(&dir, "k").as_ref(), Some(&mesh));
        assert!(load(&dir, "other").is_none());
        let p = entry_path(&dir, "k");
        let mut bytes = std::fs::read(&p).unwrap();
        let n = bytes.len();
        bytes[n - 20] ^= 1;
        std::fs::write(&p, &bytes).unwrap();
        assert!(load(&dir, "k").is_none());
        std::fs::write(&p, &bytes[..10]).unwrap();
        assert!(load(&dir, "k").is_none());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
