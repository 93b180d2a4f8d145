//! EuRoC camera `sensor.yaml` parser on arbitrary text: never panics; an accepted camera has
//! finite positive focal lengths, a non-empty image and a finite, proper body-from-camera pose.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamkit_io::euroc::parse_sensor_yaml;

fuzz_target!(|text: &str| {
    if let Ok(camera) = parse_sensor_yaml(text, "sensor.yaml") {
        let k = &camera.camera.intrinsics;
        assert!(k.fx > 0.0 && k.fy > 0.0 && k.fx.is_finite() && k.fy.is_finite());
        assert!(k.cx.is_finite() && k.cy.is_finite() && k.width > 0 && k.height > 0);
        let pose = camera.body_from_camera;
        assert!(pose.translation.vector.iter().all(|c| c.is_finite()));
        let q = pose.rotation.coords;
        assert!(q.iter().all(|c| c.is_finite()) && (q.norm() - 1.0).abs() < 1e-9);
    }
});
