//! 3D pose graphs in g2o's text format (Kümmerle et al., "g2o: a general framework for graph
//! optimization", ICRA 2011), the format of the standard pose-graph benchmarks (parking garage,
//! sphere, torus, cubicle; Carlone et al., ICRA 2015).
//!
//! Three elements are read, one per line:
//! * `VERTEX_SE3:QUAT id x y z qx qy qz qw`: the pose `world_from_vertex`;
//! * `EDGE_SE3:QUAT i j x y z qx qy qz qw` followed by the 21 upper-triangular entries of the
//!   6×6 information matrix, row by row, in the order `x y z` then rotation: the measured pose
//!   of `j` in the frame of `i`;
//! * `FIX id ...`: vertices held fixed.
//!
//! Blank lines and `#` comments are skipped. The reader is strict, since a pose graph is the
//! whole input of an optimisation: any other element, a wrong number of values, a non-finite
//! value, a quaternion far from unit length, an information matrix that is not symmetric
//! positive definite, a duplicate vertex, a self-loop, or an edge or `FIX` naming a vertex the
//! file does not declare is an error naming the line.

use crate::error::read_text;
use crate::relations::parse_numbers;
use crate::IoError;
use nalgebra::{Matrix6, Quaternion, Translation3, UnitQuaternion};
use slamkit_core::Pose3;
use std::collections::HashMap;
use std::path::Path;

/// How far from 1 a quaternion's norm may be (the file's rounding) before it is refused.
const QUATERNION_NORM_TOLERANCE: f64 = 1e-3;

/// One pose of the graph.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct G2oVertex {
    /// The id the file gives the vertex.
    pub id: i64,
    /// The vertex's pose.
    pub world_from_vertex: Pose3,
}

/// One relative pose measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct G2oEdge {
    /// Index (into [`G2oGraph::vertices`]) of the vertex the measurement is expressed in.
    pub from: usize,
    /// Index of the measured vertex.
    pub to: usize,
    /// Measured pose of `to` in the frame of `from`.
    pub from_from_to: Pose3,
    /// Information matrix of the error, ordered `x y z` then rotation (symmetric, positive
    /// definite).
    pub information: Matrix6<f64>,
}

/// A pose graph as read from a g2o file.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct G2oGraph {
    /// The vertices in file order.
    pub vertices: Vec<G2oVertex>,
    /// The edges in file order, naming vertices by index.
    pub edges: Vec<G2oEdge>,
    /// Indices of the vertices held fixed, in file order.
    pub fixed: Vec<usize>,
}

/// Parses g2o text; errors name the line (file `<input>`).
///
/// ```
/// let text = "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\n\
///             VERTEX_SE3:QUAT 1 1 0 0 0 0 0 1\n\
///             EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n";
/// let graph = slamkit_io::g2o::parse_g2o(text).unwrap();
/// assert_eq!((graph.vertices.len(), graph.edges.len()), (2, 1));
/// assert_eq!(graph.edges[0].from_from_to.translation.x, 1.0);
///
/// let err = slamkit_io::g2o::parse_g2o("VERTEX_SE3:QUAT 0 0 0\n").unwrap_err();
/// assert!(err.to_string().starts_with("<input>:1:"));
/// ```
pub fn parse_g2o(text: &str) -> Result<G2oGraph, IoError> {
    parse_g2o_named(text, "<input>")
}

/// Reads a g2o file; errors name the file and line.
pub fn read_g2o(path: &Path) -> Result<G2oGraph, IoError> {
    parse_g2o_named(&read_text(path)?, &path.display().to_string())
}

/// A vertex reference not yet resolved: the id and the line naming it.
type PendingId = (i64, usize);

fn parse_g2o_named(text: &str, file: &str) -> Result<G2oGraph, IoError> {
    let mut graph = G2oGraph::default();
    let mut index_of: HashMap<i64, usize> = HashMap::new();
    let mut edge_ids: Vec<(PendingId, PendingId)> = Vec::new();
    let mut fixed_ids: Vec<PendingId> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let number = i + 1;
        let err = |message: String| IoError::parse(file, number, message);
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let (tag, rest) = line.split_once(char::is_whitespace).unwrap_or((line, ""));
        match tag {
            "VERTEX_SE3:QUAT" => {
                let (id, rest) =
                    split_id(rest).ok_or_else(|| err("expected a vertex id".into()))?;
                let values: [f64; 7] = parse_numbers(rest).ok_or_else(|| {
                    err("VERTEX_SE3:QUAT needs an id and 7 finite numbers".into())
                })?;
                let pose = pose(&values).map_err(err)?;
                if index_of.insert(id, graph.vertices.len()).is_some() {
                    return Err(err(format!("vertex {id} is declared twice")));
                }
                graph.vertices.push(G2oVertex {
                    id,
                    world_from_vertex: pose,
                });
            }
            "EDGE_SE3:QUAT" => {
                let (from, rest) =
                    split_id(rest).ok_or_else(|| err("expected two vertex ids".into()))?;
                let (to, rest) =
                    split_id(rest).ok_or_else(|| err("expected two vertex ids".into()))?;
                let values: [f64; 28] = parse_numbers(rest).ok_or_else(|| {
                    err(
                        "EDGE_SE3:QUAT needs two ids, 7 pose and 21 information values, all finite"
                            .into(),
                    )
                })?;
                if from == to {
                    return Err(err(format!("edge joins vertex {from} to itself")));
                }
                let (measurement, upper) = values.split_at(7);
                graph.edges.push(G2oEdge {
                    from: 0,
                    to: 0,
                    from_from_to: pose(measurement).map_err(err)?,
                    information: information(upper).map_err(err)?,
                });
                edge_ids.push(((from, number), (to, number)));
            }
            "FIX" => {
                let ids: Vec<i64> = rest
                    .split_ascii_whitespace()
                    .map(|t| t.parse::<i64>().ok())
                    .collect::<Option<_>>()
                    .filter(|ids: &Vec<i64>| !ids.is_empty())
                    .ok_or_else(|| err("FIX needs one or more vertex ids".into()))?;
                fixed_ids.extend(ids.into_iter().map(|id| (id, number)));
            }
            other => {
                return Err(err(format!(
                    "unsupported element '{other}' (reads VERTEX_SE3:QUAT, EDGE_SE3:QUAT and FIX)"
                )))
            }
        }
    }
    if graph.vertices.is_empty() {
        return Err(IoError::Empty {
            file: file.to_string(),
            what: "VERTEX_SE3:QUAT".into(),
        });
    }
    let resolve = |(id, line): PendingId| {
        index_of
            .get(&id)
            .copied()
            .ok_or_else(|| IoError::parse(file, line, format!("vertex {id} is not declared")))
    };
    for (edge, (from, to)) in graph.edges.iter_mut().zip(edge_ids) {
        edge.from = resolve(from)?;
        edge.to = resolve(to)?;
    }
    graph.fixed = fixed_ids
        .into_iter()
        .map(resolve)
        .collect::<Result<_, _>>()?;
    Ok(graph)
}

/// The first token of `rest` as an integer id, and what follows it.
fn split_id(rest: &str) -> Option<(i64, &str)> {
    let rest = rest.trim_start();
    let (id, tail) = rest.split_once(char::is_whitespace).unwrap_or((rest, ""));
    Some((id.parse().ok()?, tail))
}

/// A pose from `x y z qx qy qz qw`, the quaternion normalised once checked to be near unit.
fn pose(values: &[f64]) -> Result<Pose3, String> {
    let [x, y, z, qx, qy, qz, qw] = values else {
        return Err(format!("expected 7 pose values, got {}", values.len()));
    };
    let q = Quaternion::new(*qw, *qx, *qy, *qz);
    let norm = q.norm();
    if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
        return Err(format!("quaternion norm {norm} is not 1"));
    }
    Ok(Pose3::from_parts(
        Translation3::new(*x, *y, *z),
        UnitQuaternion::from_quaternion(q),
    ))
}

/// The symmetric information matrix from its 21 upper-triangular entries, row by row; it must
/// be positive definite.
fn information(upper: &[f64]) -> Result<Matrix6<f64>, String> {
    if upper.len() != 21 {
        return Err(format!(
            "expected 21 information values, got {}",
            upper.len()
        ));
    }
    let mut m = Matrix6::zeros();
    let mut values = upper.iter();
    for r in 0..6 {
        for c in r..6 {
            let v = values.next().copied().unwrap_or(f64::NAN);
            m[(r, c)] = v;
            m[(c, r)] = v;
        }
    }
    if nalgebra::Cholesky::new(m).is_none() {
        return Err("information matrix is not positive definite".into());
    }
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;

    const IDENTITY_INFO: &str = "1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1";

    fn edge_line(from: &str, to: &str, info: &str) -> String {
        format!("EDGE_SE3:QUAT {from} {to} 1 2 3 0 0 0.7071067811865476 0.7071067811865476 {info}")
    }

    #[test]
    fn reads_vertices_edges_and_fixed_ones() {
        let text = format!(
            "# a comment\nVERTEX_SE3:QUAT 10 1 2 3 0 0 0 1\n\nVERTEX_SE3:QUAT 20 0 0 0 0 0 0.7071067811865476 0.7071067811865476\n{}\nFIX 20\n",
            edge_line("10", "20", "100 2 3 4 5 6 10 0 0 0 0 10 0 0 0 10 0 0 10 0 10")
        );
        let g = parse_g2o(&text).unwrap();
        assert_eq!(g.vertices.len(), 2);
        assert_eq!(g.vertices[1].id, 20);
        assert_eq!(g.vertices[0].world_from_vertex.translation.vector.z, 3.0);
        let yaw = g.vertices[1].world_from_vertex.rotation.euler_angles().2;
        assert!((yaw - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let e = &g.edges[0];
        assert_eq!((e.from, e.to), (0, 1));
        assert_eq!(e.from_from_to.translation.vector.y, 2.0);
        // Row 0 is 100 2 3 4 5 6; the matrix is symmetric.
        assert_eq!(e.information[(0, 5)], 6.0);
        assert_eq!(e.information[(5, 0)], 6.0);
        assert_eq!(e.information[(1, 1)], 10.0);
        assert_eq!(g.fixed, vec![1]);
    }

    #[test]
    fn bad_input_names_the_line() {
        let v = "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 0 0 0 0 0 0 1\n";
        let cases = [
            (
                format!("{v}VERTEX_SE3:QUAT 2 0 0 0 0 0 0\n"),
                3,
                "7 finite numbers",
            ),
            (
                format!("{v}VERTEX_SE3:QUAT 1 0 0 0 0 0 0 1\n"),
                3,
                "declared twice",
            ),
            (
                format!("{v}VERTEX_SE3:QUAT x 0 0 0 0 0 0 1\n"),
                3,
                "vertex id",
            ),
            (
                format!("{v}VERTEX_SE3:QUAT 2 0 0 0 0 0 0 2\n"),
                3,
                "quaternion norm",
            ),
            (
                format!("{v}VERTEX_SE3:QUAT 2 0 nan 0 0 0 0 1\n"),
                3,
                "finite",
            ),
            (
                format!("{v}{}\n", edge_line("0", "1", "1 0 0")),
                3,
                "21 information",
            ),
            (
                format!("{v}{}\n", edge_line("0", "0", IDENTITY_INFO)),
                3,
                "itself",
            ),
            (
                format!("{v}{}\n", edge_line("0", "7", IDENTITY_INFO)),
                3,
                "vertex 7 is not",
            ),
            (
                format!(
                    "{v}{}\n",
                    edge_line("0", "1", &IDENTITY_INFO.replace("1 0 1", "1 0 -1"))
                ),
                3,
                "positive definite",
            ),
            (format!("{v}FIX\n"), 3, "FIX needs"),
            (format!("{v}FIX 0 9\n"), 3, "vertex 9 is not"),
            (
                format!("{v}VERTEX_SE2 2 0 0 0\n"),
                3,
                "unsupported element 'VERTEX_SE2'",
            ),
        ];
        for (text, line, message) in cases {
            let err = parse_g2o(&text).unwrap_err().to_string();
            assert!(err.starts_with(&format!("<input>:{line}:")), "{err}");
            assert!(err.contains(message), "{err} lacks {message}");
            assert!(!err.contains('\n'), "{err}");
        }
        let empty = parse_g2o("# nothing\n").unwrap_err().to_string();
        assert!(empty.contains("no data"), "{empty}");
    }

    #[test]
    fn a_missing_file_names_it() {
        let err = read_g2o(Path::new("/nonexistent/graph.g2o")).unwrap_err();
        assert!(err.to_string().contains("/nonexistent/graph.g2o"));
    }
}
