//! OctoMap's binary `.bt` format, written and read.
//!
//! Layout (OctoMap 1.10, `AbstractOcTree::write` / `OccupancyOcTreeBase::writeBinaryNode`): a
//! text header — `# Octomap OcTree binary file`, comment lines, `id OcTree`, `size <nodes>`,
//! `res <resolution>`, `data` — then the maximum-likelihood tree depth first from the root. Each
//! inner node is two bytes holding two bits per child, children 0–3 in the first byte and 4–7 in
//! the second, child `i` at bits `2i, 2i+1`: `00` unknown (no child), bit `2i` alone free leaf,
//! bit `2i+1` alone occupied leaf, both an inner node whose own two bytes follow, in child
//! order. Reading gives leaves the clamp limits of their class, inner nodes the largest child,
//! as OctoMap's reader does.

use super::nodes::{NO_CHILDREN, ROOT};
use super::{Octree, OctreeConfig};
use crate::error::MapFileError;
use std::path::Path;

/// First line of every `.bt` file.
const HEADER: &str = "# Octomap OcTree binary file";

/// The `.bt` bytes of `tree` (its maximum-likelihood, pruned form).
pub fn bt_bytes(tree: &Octree) -> Vec<u8> {
    let ml = tree.to_max_likelihood();
    let nodes = ml.pool.count_existing();
    let mut out = format!(
        "{HEADER}\n# (feel free to add / change comments, but leave the first line as it is!)\n#\n\
         id OcTree\nsize {nodes}\nres {}\ndata\n",
        tree.config.resolution_m
    )
    .into_bytes();
    if ml.pool.exists(ROOT) {
        write_node(&ml, ROOT, &mut out);
    }
    out
}

/// Writes `tree` to `path` in `.bt` format.
pub fn write_bt(tree: &Octree, path: &Path) -> Result<(), MapFileError> {
    std::fs::write(path, bt_bytes(tree)).map_err(|source| MapFileError::Io {
        path: path.to_path_buf(),
        source,
    })
}

fn write_node(tree: &Octree, node: u32, out: &mut Vec<u8>) {
    let first = tree.pool.first_child(node);
    let mut bits = 0u16;
    for i in 0..8u32 {
        let child = first + i;
        if !tree.pool.exists(child) {
            continue;
        }
        let code = if tree.pool.first_child(child) != NO_CHILDREN {
            0b11
        } else if tree.classify(tree.pool.value(child)) == crate::Occupancy::Occupied {
            0b10
        } else {
            0b01
        };
        bits |= code << (2 * i);
    }
    out.extend_from_slice(&bits.to_le_bytes());
    for i in 0..8u32 {
        let child = first + i;
        if tree.pool.exists(child) && tree.pool.first_child(child) != NO_CHILDREN {
            write_node(tree, child, out);
        }
    }
}

/// Reads a `.bt` file into an octree with `config`'s sensor model and the file's resolution.
pub fn read_bt(path: &Path, config: &OctreeConfig) -> Result<Octree, MapFileError> {
    let bytes = std::fs::read(path).map_err(|source| MapFileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_bt(&bytes, path, config)
}

/// Parses `.bt` bytes; `path` only names the source in errors.
pub fn parse_bt(bytes: &[u8], path: &Path, config: &OctreeConfig) -> Result<Octree, MapFileError> {
    let format = |message: String| MapFileError::Octree {
        path: path.to_path_buf(),
        message,
    };
    let (resolution_m, size, mut pos) = parse_header(bytes).map_err(format)?;
    let config = OctreeConfig {
        resolution_m,
        ..config.clone()
    };
    let mut tree = Octree::new(config).map_err(|source| MapFileError::Map {
        path: path.to_path_buf(),
        source,
    })?;
    if size > 0 {
        tree.pool.set_value(ROOT, 0.0);
        read_node(&mut tree, ROOT, 0, bytes, &mut pos).map_err(format)?;
    }
    Ok(tree)
}

/// Resolution, node count and the offset of the data of a `.bt` file.
fn parse_header(bytes: &[u8]) -> Result<(f64, usize, usize), String> {
    let mut pos = 0;
    let mut line_no = 0;
    let (mut resolution, mut size) = (None, None);
    loop {
        let Some(len) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err("header ends before `data`".into());
        };
        let line = String::from_utf8_lossy(&bytes[pos..pos + len])
            .trim()
            .to_string();
        pos += len + 1;
        line_no += 1;
        if line_no == 1 && !line.starts_with(HEADER) {
            return Err(format!("first line is not `{HEADER}`"));
        }
        let mut words = line.split_whitespace();
        match (words.next(), words.next()) {
            (Some("data"), _) => break,
            (Some("id"), Some(id)) if id != "OcTree" => {
                return Err(format!(
                    "line {line_no}: tree type {id}, only OcTree is supported"
                ))
            }
            (Some("size"), Some(v)) => size = v.parse::<usize>().ok(),
            (Some("res"), Some(v)) => resolution = v.parse::<f64>().ok(),
            _ => {}
        }
    }
    match (resolution, size) {
        (Some(r), Some(s)) => Ok((r, s, pos)),
        _ => Err("header lacks a valid `size` or `res` line".into()),
    }
}

fn read_node(
    tree: &mut Octree,
    node: u32,
    depth: u32,
    bytes: &[u8],
    pos: &mut usize,
) -> Result<(), String> {
    let Some(pair) = bytes.get(*pos..*pos + 2) else {
        return Err(format!("data truncated at byte {pos}"));
    };
    let bits = u16::from_le_bytes([pair[0], pair[1]]);
    *pos += 2;
    if bits == 0 {
        return Ok(());
    }
    if depth >= super::key::TREE_DEPTH {
        return Err(format!("node at byte {} lies below depth 16", *pos - 2));
    }
    let first = tree.pool.add_children(node);
    for i in 0..8u32 {
        let value = match (bits >> (2 * i)) & 0b11 {
            0b01 => tree.l_min,
            0b10 => tree.l_max,
            0b11 => 0.0,
            _ => continue,
        };
        tree.pool.set_value(first + i, value);
    }
    for i in 0..8u32 {
        if (bits >> (2 * i)) & 0b11 == 0b11 {
            read_node(tree, first + i, depth + 1, bytes, pos)?;
        }
    }
    tree.pool.prune_or_update(node);
    Ok(())
}
