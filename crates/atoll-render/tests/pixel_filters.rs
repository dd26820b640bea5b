//! pbrt-v4's pixel filters on a sky-lit checkerboard: every pixel converges
//! to the checkerboard convolved with the filter around the pixel's centre,
//! edges blurred by the Gaussian and the triangle and overshooting under
//! Mitchell's and Lanczos's negative lobes (whose samples weigh negative).

mod common;

use common::{assert_pixels_match, render_against, sky_lit_plane};
use glam::{Vec2, Vec3};

/// Checks of 0.9 and 0.1 half a unit wide (about four pixels).
const CHECKS: &str =
    "Texture \"reflectance\" \"spectrum\" \"checkerboard\" \"float uscale\" 40 \"float vscale\" 40 \
                      \"rgb tex1\" [ 0.9 0.9 0.9 ] \"rgb tex2\" [ 0.1 0.1 0.1 ]";

fn checks(p: Vec3) -> Vec3 {
    let st = (Vec2::new(p.x, p.y) + 10.0) / 20.0 * 40.0;
    Vec3::splat(if (st.x.floor() + st.y.floor()).rem_euclid(2.0) == 0.0 { 0.9 } else { 0.1 })
}

fn check(filter: &str, median: f32, p99: f32) -> Vec<Vec3> {
    let (film, want) = render_against(&sky_lit_plane(24, 1024, filter, CHECKS), &checks);
    assert_pixels_match(filter, &film, &want, median, p99);
    want
}

#[test]
fn positive_filters_blur_edges() {
    // Pixels between the checks' values: edges, more of them the wider the filter.
    let between = |want: &[Vec3]| want.iter().filter(|v| v.x > 0.15 && v.x < 0.85).count();
    let pixel = between(&check("PixelFilter \"box\"", 0.02, 0.08));
    let wide_box =
        between(&check("PixelFilter \"box\" \"float xradius\" 1 \"float yradius\" 0.75", 0.02, 0.08));
    // A scene without a PixelFilter gets pbrt-v4's Gaussian.
    let gaussian = between(&check("", 0.02, 0.08));
    let triangle = between(&check("PixelFilter \"triangle\" \"float xradius\" 1.5", 0.02, 0.08));
    assert!(
        pixel < wide_box && pixel < gaussian && pixel < triangle,
        "{pixel} {wide_box} {gaussian} {triangle}"
    );
}

#[test]
fn negative_lobes_overshoot_at_edges() {
    for filter in ["PixelFilter \"mitchell\"", "PixelFilter \"sinc\" \"float xradius\" 3 \"float yradius\" 3"]
    {
        let want = check(filter, 0.03, 0.12);
        assert!(want.iter().any(|v| v.x > 0.92 || v.x < 0.08), "{filter}: no pixel rings past the checks");
    }
}
