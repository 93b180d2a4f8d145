use super::*;
use crate::test_room::room_scan;
use nalgebra::Vector2;
use slamkit_core::Pose2;

fn room_grid() -> OccupancyGrid {
    let mut grid = OccupancyGrid::new(OccupancyGridConfig::default()).unwrap();
    for (x, y) in [(0.0, 0.0), (1.0, -1.0)] {
        let pose = Pose2::new(Vector2::new(x, y), 0.5);
        grid.insert_scan(&room_scan(&pose, 2.025, 360, 30.0), &pose)
            .unwrap();
    }
    grid
}

/// Every cell of `a`'s known area (and a border around it) has the same tri-state in `b`.
fn assert_same_tri_state(a: &OccupancyGrid, b: &OccupancyGrid) {
    let bounds = a.known_bounds().unwrap();
    let mut counts = [0usize; 3];
    for y in bounds.min.y - 2..=bounds.max.y + 2 {
        for x in bounds.min.x - 2..=bounds.max.x + 2 {
            let centre = a.cell_center_m(CellIndex { x, y });
            let expected = a.occupancy_at(&centre).unwrap_or(Occupancy::Unknown);
            let got = b.occupancy_at(&centre).unwrap_or(Occupancy::Unknown);
            assert_eq!(got, expected, "cell ({x}, {y})");
            counts[expected as usize] += 1;
        }
    }
    assert!(counts.iter().all(|&c| c > 100), "{counts:?}");
}

#[test]
fn pgm_yaml_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let grid = room_grid();
    let yaml_path = dir.path().join("map.yaml");
    save_map_yaml(&grid, &yaml_path).unwrap();
    let text = std::fs::read_to_string(&yaml_path).unwrap();
    assert!(text.contains("image: map.pgm\n"), "{text}");
    assert!(text.contains("resolution: 0.05\n"));
    assert!(text.contains("origin: [-2.05, -2.05, 0]\n"), "{text}");
    assert!(text.contains("negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"));
    let loaded = load_map_yaml(&yaml_path).unwrap();
    assert_eq!(loaded.resolution_m(), 0.05);
    assert_same_tri_state(&grid, &loaded);
    let (l_min, l_max) = loaded.log_odds_limits();
    let wall = Point2::new(2.02, 0.3);
    assert_eq!(loaded.log_odds_at(&wall), Some(l_max));
    assert_eq!(loaded.log_odds_at(&Point2::new(0.0, 0.0)), Some(l_min));
}

#[test]
fn pgm_pixels_follow_map_server_convention() {
    let mut grid = OccupancyGrid::new(OccupancyGridConfig::default()).unwrap();
    grid.set_log_odds(CellIndex { x: 0, y: 0 }, 1.0).unwrap();
    grid.set_log_odds(CellIndex { x: 2, y: 1 }, -1.0).unwrap();
    let image = trinary_image(&grid);
    assert_eq!((image.width, image.height), (3, 2));
    // Top row is y = 1.
    assert_eq!(image.pixels, vec![205, 205, 254, 0, 205, 205]);
    assert_eq!(image.origin_m, Point2::new(0.0, 0.0));
    let dir = tempfile::tempdir().unwrap();
    save_map_yaml(&grid, &dir.path().join("m.yaml")).unwrap();
    let bytes = std::fs::read(dir.path().join("m.pgm")).unwrap();
    assert!(bytes.starts_with(b"P5\n"));
    assert!(bytes.ends_with(&[205, 205, 254, 0, 205, 205]));
    assert_eq!(parse_pgm(&bytes).unwrap(), (3, 2, image.pixels));
}

#[test]
fn png_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let grid = room_grid();
    save_png(&grid, &dir.path().join("map.png")).unwrap();
    let image = trinary_image(&grid);
    let yaml = MapYaml {
        image: "map.png".into(),
        resolution_m: 0.05,
        origin: [image.origin_m.x, image.origin_m.y, 0.0],
        negate: false,
        occupied_thresh: 0.65,
        free_thresh: 0.196,
    };
    let yaml_path = dir.path().join("png_map.yaml");
    std::fs::write(&yaml_path, yaml.to_yaml_string()).unwrap();
    assert_same_tri_state(&grid, &load_map_yaml(&yaml_path).unwrap());
}

#[test]
fn hand_written_ros_yaml_with_negate() {
    let dir = tempfile::tempdir().unwrap();
    // 2 x 2 PGM with maxval 100 and a comment: white (100) is occupied when negated.
    let mut pgm = b"P5 # made by hand\n2 2\n100\n".to_vec();
    pgm.extend_from_slice(&[100, 0, 50, 100]);
    std::fs::write(dir.path().join("tiny.pgm"), pgm).unwrap();
    let yaml = "# ROS map\nimage: \"tiny.pgm\"\nmode: trinary\nresolution: 0.5\n\
                origin: [-1.0, 2.0, 0.0]\nnegate: 1\noccupied_thresh: 0.65\nfree_thresh: 0.25\n";
    let yaml_path = dir.path().join("tiny.yaml");
    std::fs::write(&yaml_path, yaml).unwrap();
    let grid = load_map_yaml(&yaml_path).unwrap();
    let at = |x, y| grid.occupancy_at(&Point2::new(x, y));
    // Top-left pixel (100) covers x in [-1, -0.5), y in [2.5, 3).
    assert_eq!(at(-0.75, 2.75), Some(Occupancy::Occupied));
    assert_eq!(at(-0.25, 2.75), Some(Occupancy::Free));
    assert_eq!(at(-0.75, 2.25), Some(Occupancy::Unknown));
    assert_eq!(at(-0.25, 2.25), Some(Occupancy::Occupied));
}

fn yaml_error(text: &str) -> MapFileError {
    parse_map_yaml(text, Path::new("bad.yaml")).unwrap_err()
}

const GOOD: &str = "image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n\
                    occupied_thresh: 0.65\nfree_thresh: 0.196\n";

#[test]
fn corrupt_yaml_gives_clear_errors() {
    assert!(parse_map_yaml(GOOD, Path::new("ok.yaml")).is_ok());
    let e = yaml_error(&GOOD.replace("resolution: 0.05\n", ""));
    assert!(
        matches!(
            e,
            MapFileError::MissingKey {
                key: "resolution",
                ..
            }
        ),
        "{e}"
    );
    let e = yaml_error(&GOOD.replace("[0, 0, 0]", "[0, 0]"));
    assert!(matches!(e, MapFileError::Yaml { line: 3, .. }), "{e}");
    assert!(e.to_string().starts_with("bad.yaml:3: origin"), "{e}");
    let e = yaml_error(&GOOD.replace("0.05", "fast"));
    assert!(matches!(e, MapFileError::Yaml { line: 2, .. }), "{e}");
    let e = yaml_error(&GOOD.replace("0.05", "-0.05"));
    assert!(matches!(e, MapFileError::Yaml { line: 2, .. }), "{e}");
    let e = yaml_error(&GOOD.replace("negate: 0", "negate: yes"));
    assert!(matches!(e, MapFileError::Yaml { line: 4, .. }), "{e}");
    let e = yaml_error(&GOOD.replace("free_thresh: 0.196", "free_thresh: 0.9"));
    assert!(matches!(e, MapFileError::Yaml { line: 6, .. }), "{e}");
    let e = yaml_error(&format!("{GOOD}just garbage\n"));
    assert!(matches!(e, MapFileError::Yaml { line: 7, .. }), "{e}");
    let e = yaml_error(&format!("{GOOD}resolution: 0.1\n"));
    assert!(e.to_string().contains("duplicate key `resolution`"), "{e}");
    let e = yaml_error(&GOOD.replace("origin: [0, 0, 0]", "origin: [NaN, 0, 0]"));
    assert!(matches!(e, MapFileError::Yaml { line: 3, .. }), "{e}");
}

#[test]
fn corrupt_pgm_gives_clear_errors() {
    let mut good = b"P5\n3 2\n255\n".to_vec();
    good.extend_from_slice(&[0; 6]);
    assert!(parse_pgm(&good).is_ok());
    assert!(parse_pgm(b"P2\n3 2\n255\n").unwrap_err().contains("P5"));
    assert!(parse_pgm(b"P5\n3").unwrap_err().contains("height"));
    assert!(parse_pgm(b"P5\n0 2\n255\n").unwrap_err().contains("size"));
    assert!(parse_pgm(b"P5\n3 2\n65535\n")
        .unwrap_err()
        .contains("8-bit"));
    assert!(parse_pgm(&good[..good.len() - 1])
        .unwrap_err()
        .contains("truncated"));
    assert!(parse_pgm(b"").is_err());
    // Through the loader the error names the image file.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("m.pgm"), &good[..12]).unwrap();
    let yaml_path = dir.path().join("m.yaml");
    std::fs::write(&yaml_path, GOOD).unwrap();
    let e = load_map_yaml(&yaml_path).unwrap_err();
    assert!(matches!(e, MapFileError::Pgm { .. }), "{e}");
    assert!(
        e.to_string().contains("m.pgm") && e.to_string().contains("truncated"),
        "{e}"
    );
    std::fs::remove_file(dir.path().join("m.pgm")).unwrap();
    assert!(matches!(
        load_map_yaml(&yaml_path),
        Err(MapFileError::Io { .. })
    ));
    let e = load_map_yaml(&dir.path().join("absent.yaml")).unwrap_err();
    assert!(e.to_string().contains("absent.yaml"), "{e}");
}

#[test]
fn rotated_origin_is_unsupported() {
    let dir = tempfile::tempdir().unwrap();
    let yaml_path = dir.path().join("m.yaml");
    std::fs::write(&yaml_path, GOOD.replace("[0, 0, 0]", "[0, 0, 0.5]")).unwrap();
    assert!(matches!(
        load_map_yaml(&yaml_path),
        Err(MapFileError::Unsupported { .. })
    ));
}

#[test]
fn empty_grid_saves_one_unknown_pixel() {
    let grid = OccupancyGrid::new(OccupancyGridConfig::default()).unwrap();
    let image = trinary_image(&grid);
    assert_eq!(
        (image.width, image.height, image.pixels),
        (1, 1, vec![UNKNOWN_PIXEL])
    );
}
