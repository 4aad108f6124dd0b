//! The first frame: a triangle rendered offscreen on lavapipe, read back and checked.

use tilegraph_e2e::gpu;
use tilegraph_vk::first_frame::render_triangle;

#[test]
fn triangle_pixels_are_where_they_belong() {
    let g = gpu(None).unwrap();
    let img = render_triangle(&g, 160, 90).unwrap();
    assert_eq!(
        (img.width, img.height, img.pixels.len()),
        (160, 90, 160 * 90 * 4)
    );
    // Corners are the clear colour (0.05, 0.05, 0.08) in UNORM.
    let clear = [13, 13, 20, 255];
    for (x, y) in [(0, 0), (159, 0), (0, 89), (159, 89)] {
        assert_eq!(img.pixel(x, y), Some(clear), "corner ({x},{y})");
    }
    // The centroid (NDC (0, 0.2) -> pixel (80, 54)) mixes the three colours about equally.
    let c = img.pixel(80, 54).unwrap();
    for ch in &c[..3] {
        assert!((70..=100).contains(ch), "centroid {c:?}");
    }
    // Near the apex (NDC y = -0.6 is the top: pixel row 18) red dominates: the image is upright.
    let apex = img.pixel(80, 20).unwrap();
    assert!(
        apex[0] > 200 && apex[1] < 50 && apex[2] < 50,
        "apex {apex:?}"
    );
    // Bottom-left vertex (-0.6, 0.6) is blue, bottom-right (0.6, 0.6) is green.
    let bl = img.pixel(34, 70).unwrap();
    let br = img.pixel(125, 70).unwrap();
    assert!(bl[2] > bl[0] && bl[2] > bl[1], "bottom-left {bl:?}");
    assert!(br[1] > br[0] && br[1] > br[2], "bottom-right {br:?}");
}

#[test]
fn first_frame_under_every_forced_profile() {
    for p in ["mali-valhall", "adreno-7xx", "powervr-b", "desktop-nvidia"] {
        let g = gpu(Some(p)).unwrap();
        let img = render_triangle(&g, 27, 13).unwrap();
        assert_eq!(img.pixels.len(), 27 * 13 * 4);
    }
}
