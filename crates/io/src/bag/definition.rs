//! ROS 2 message definitions stored in a bag (MCAP schemas of encoding `ros2msg`, the
//! `message_definitions` table of a `.db3`), checked against the layouts slamkit's decoders
//! are written for. ROS 2 has no md5sum; comparing the stored definition field by field is
//! what tells that a topic of the right name holds the version of the type slamkit reads.
//!
//! A stored definition is the type's `.msg` text, then each nested type's after a line of
//! `=` and a `MSG: package/Type` line. Only the field types are compared (names do not
//! change the bytes): comments, constants (`uint8 ULTRASOUND=0`) and default values are
//! dropped, `package/msg/Type` is read as `package/Type`, a type without a package is one of
//! the section's own package, and `byte` and `char` are `uint8`. A nested type whose section
//! the bag does not store is not compared.

use std::collections::HashMap;

/// The layouts the decoders read: type, then its fields' types (ROS 2 spelling).
const LAYOUTS: &[(&str, &[&str])] = &[
    ("builtin_interfaces/Time", &["int32", "uint32"]),
    ("std_msgs/Header", &["builtin_interfaces/Time", "string"]),
    ("geometry_msgs/Point", &["float64"; 3]),
    ("geometry_msgs/Vector3", &["float64"; 3]),
    ("geometry_msgs/Quaternion", &["float64"; 4]),
    (
        "geometry_msgs/Pose",
        &["geometry_msgs/Point", "geometry_msgs/Quaternion"],
    ),
    (
        "geometry_msgs/PoseWithCovariance",
        &["geometry_msgs/Pose", "float64[36]"],
    ),
    (
        "geometry_msgs/Twist",
        &["geometry_msgs/Vector3", "geometry_msgs/Vector3"],
    ),
    (
        "geometry_msgs/TwistWithCovariance",
        &["geometry_msgs/Twist", "float64[36]"],
    ),
    (
        "geometry_msgs/Transform",
        &["geometry_msgs/Vector3", "geometry_msgs/Quaternion"],
    ),
    (
        "geometry_msgs/TransformStamped",
        &["std_msgs/Header", "string", "geometry_msgs/Transform"],
    ),
    ("tf2_msgs/TFMessage", &["geometry_msgs/TransformStamped[]"]),
    (
        "nav_msgs/Odometry",
        &[
            "std_msgs/Header",
            "string",
            "geometry_msgs/PoseWithCovariance",
            "geometry_msgs/TwistWithCovariance",
        ],
    ),
    (
        "sensor_msgs/LaserScan",
        &[
            "std_msgs/Header",
            "float32",
            "float32",
            "float32",
            "float32",
            "float32",
            "float32",
            "float32",
            "float32[]",
            "float32[]",
        ],
    ),
    (
        "sensor_msgs/Range",
        &[
            "std_msgs/Header",
            "uint8",
            "float32",
            "float32",
            "float32",
            "float32",
        ],
    ),
    (
        "sensor_msgs/Imu",
        &[
            "std_msgs/Header",
            "geometry_msgs/Quaternion",
            "float64[9]",
            "geometry_msgs/Vector3",
            "float64[9]",
            "geometry_msgs/Vector3",
            "float64[9]",
        ],
    ),
    (
        "sensor_msgs/Image",
        &[
            "std_msgs/Header",
            "uint32",
            "uint32",
            "string",
            "uint8",
            "uint32",
            "uint8[]",
        ],
    ),
    (
        "sensor_msgs/CompressedImage",
        &["std_msgs/Header", "string", "uint8[]"],
    ),
    (
        "sensor_msgs/RegionOfInterest",
        &["uint32", "uint32", "uint32", "uint32", "bool"],
    ),
    (
        "sensor_msgs/CameraInfo",
        &[
            "std_msgs/Header",
            "uint32",
            "uint32",
            "string",
            "float64[]",
            "float64[9]",
            "float64[9]",
            "float64[12]",
            "uint32",
            "uint32",
            "sensor_msgs/RegionOfInterest",
        ],
    ),
];

const PRIMITIVES: &[&str] = &[
    "bool", "byte", "char", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64",
    "uint64", "float32", "float64", "string", "wstring", "time", "duration",
];

/// A type name without its `msg` part: `sensor_msgs/msg/LaserScan` → `sensor_msgs/LaserScan`.
///
/// ```
/// use slamkit_io::bag::definition::ros2_type_name;
/// assert_eq!(ros2_type_name("sensor_msgs/msg/LaserScan"), "sensor_msgs/LaserScan");
/// assert_eq!(ros2_type_name("nav_msgs/Odometry"), "nav_msgs/Odometry");
/// ```
pub fn ros2_type_name(name: &str) -> String {
    match name.split('/').collect::<Vec<_>>().as_slice() {
        [pkg, "msg", ty] => format!("{pkg}/{ty}"),
        _ => name.to_string(),
    }
}

/// A field type as compared: package-qualified, aliases resolved, bounds kept.
fn normalise(ty: &str, package: &str) -> String {
    let (base, array) = match ty.find('[') {
        Some(i) => ty.split_at(i),
        None => (ty, ""),
    };
    let base = match base {
        "byte" | "char" => "uint8".to_string(),
        b if PRIMITIVES.contains(&b) || b.starts_with("string<=") => b.to_string(),
        b if b.contains('/') => ros2_type_name(b),
        "Header" => "std_msgs/Header".to_string(),
        b => format!("{package}/{b}"),
    };
    format!("{base}{array}")
}

/// The sections of a stored definition: type → its field types.
fn sections(top: &str, text: &str) -> HashMap<String, Vec<String>> {
    let mut out = HashMap::new();
    let mut name = top.to_string();
    let mut fields = Vec::new();
    for line in text.lines() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.starts_with("==") {
            out.insert(std::mem::take(&mut name), std::mem::take(&mut fields));
            continue;
        }
        if let Some(nested) = line.strip_prefix("MSG:") {
            name = ros2_type_name(nested.trim());
            continue;
        }
        let mut tokens = line.split_whitespace();
        let (Some(ty), Some(field)) = (tokens.next(), tokens.next()) else {
            continue;
        };
        if field.contains('=') || tokens.next().is_some_and(|t| t.starts_with('=')) {
            continue; // a constant
        }
        let package = name.split('/').next().unwrap_or("");
        fields.push(normalise(ty, package));
    }
    out.insert(name, fields);
    out.remove("");
    out
}

/// Checks the stored ROS 2 definition `text` of type `ty` (`sensor_msgs/LaserScan`) against
/// the layout slamkit decodes; an empty `text` (a bag storing no definitions) passes. `Err`
/// names the first difference.
///
/// ```
/// use slamkit_io::bag::definition::check_definition;
///
/// let stored = "std_msgs/Header header # time of the reading\n\
///               string format\nuint8[] data\n\
///               ================================================================================\n\
///               MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n";
/// assert!(check_definition("sensor_msgs/CompressedImage", stored).is_ok());
/// let older = stored.replace("uint8[] data", "uint16[] data");
/// let err = check_definition("sensor_msgs/CompressedImage", &older).unwrap_err();
/// assert!(err.contains("field 3"), "{err}");
/// ```
pub fn check_definition(ty: &str, text: &str) -> Result<(), String> {
    if text.trim().is_empty() {
        return Ok(());
    }
    let stored = sections(ty, text);
    let mut todo = vec![ty.to_string()];
    let mut seen = Vec::new();
    while let Some(name) = todo.pop() {
        if seen.contains(&name) {
            continue;
        }
        let Some((_, want)) = LAYOUTS.iter().find(|(n, _)| *n == name) else {
            return Err(format!("{name} is not a type slamkit reads"));
        };
        if let Some(got) = stored.get(&name) {
            if got.len() != want.len() {
                return Err(format!(
                    "{name} has {} fields, slamkit reads {}",
                    got.len(),
                    want.len()
                ));
            }
            for (i, (g, w)) in got.iter().zip(want.iter()).enumerate() {
                if g != w {
                    return Err(format!("{name} field {}: {g}, slamkit reads {w}", i + 1));
                }
            }
        }
        for w in want.iter() {
            let base = w.split('[').next().unwrap_or(w);
            if base.contains('/') {
                todo.push(base.to_string());
            }
        }
        seen.push(name);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_layout_refers_to_known_types() {
        for (name, fields) in LAYOUTS {
            for f in fields.iter() {
                let base = f.split('[').next().unwrap();
                assert!(
                    PRIMITIVES.contains(&base) || LAYOUTS.iter().any(|(n, _)| *n == base),
                    "{name}: {f}"
                );
            }
        }
    }

    #[test]
    fn relative_names_constants_and_a_missing_field() {
        let text = "uint8 ULTRASOUND=0\nuint8 INFRARED = 1\nstd_msgs/Header header\n\
                    uint8 radiation_type\nfloat32 field_of_view\nfloat32 min_range\n\
                    float32 max_range\nfloat32 range\n";
        assert!(check_definition("sensor_msgs/Range", text).is_ok());
        let cam = "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n\
                   float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\n\
                   uint32 binning_y\nRegionOfInterest roi\n=====\nMSG: sensor_msgs/RegionOfInterest\n\
                   uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\n";
        let err = check_definition("sensor_msgs/CameraInfo", cam).unwrap_err();
        assert!(err.contains("RegionOfInterest has 4 fields"), "{err}");
        assert!(
            check_definition("sensor_msgs/CameraInfo", &format!("{cam}bool do_rectify\n")).is_ok()
        );
    }
}
