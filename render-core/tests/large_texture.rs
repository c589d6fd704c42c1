//! Hard case (issue 7): a 16k x 16k texture, the largest side accepted, decodes, mip-maps
//! and filters within a stated memory budget: 8-bit texels stay 8-bit, and the pyramid adds a
//! third. Decoders and render-core are optimised in test builds (Cargo.toml), so this takes a
//! few seconds.

use glam::Vec2;
use render_core::texture::{ColorSpace, Image, MAX_TEXTURE_SIDE, Texture, Wrap};

#[test]
fn a_16k_texture_fits_its_budget_and_filters_to_its_mean() {
    let side = MAX_TEXTURE_SIDE;
    // A grey image with a bright 1024-texel square in one corner, encoded as PNG.
    let mut img = image::GrayImage::from_pixel(side, side, image::Luma([64u8]));
    for y in 0..1024 {
        for x in 0..1024 {
            img.put_pixel(x, y, image::Luma([255]));
        }
    }
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).expect("encodes");
    drop(img);
    let image = Image::decode(&png, "huge.png").expect("a 16k texture decodes");
    assert_eq!(image.size(), (side, side));
    assert_eq!(image.bytes(), (side as usize) * (side as usize), "one byte per grey texel");
    let texture = Texture::new(&image, ColorSpace::Raw);
    drop(image);
    assert_eq!(texture.level_count(), 15);
    // The whole pyramid costs at most 4/3 of the finest level (268 MiB -> 358 MiB).
    let base = (side as usize) * (side as usize);
    assert!(texture.bytes() <= base * 4 / 3 + 64, "{} bytes for a {base}-byte image", texture.bytes());
    // Finest level: exact texels; coarsest: the mean, in linear values.
    let at = |st: Vec2, lod: f32| texture.lookup(st, lod, [Wrap::Clamp; 2]).x;
    assert!((at(Vec2::new(0.5, 0.5), 0.0) - 64.0 / 255.0).abs() < 1e-6);
    assert!((at(Vec2::new(0.01, 0.99), 0.0) - 1.0).abs() < 1e-6, "the bright square is top-left");
    let mean = (64.0 * (1.0 - 1.0 / 256.0) + 255.0 / 256.0) / 255.0;
    assert!((at(Vec2::splat(0.5), 20.0) - mean).abs() < 2.0 / 255.0, "coarsest {} vs mean {mean}", at(Vec2::splat(0.5), 20.0));
    // One past the limit is refused from the header alone.
    let too_big = image::GrayImage::new(side + 1, 1);
    let mut png = Vec::new();
    too_big.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).unwrap();
    assert!(Image::decode(&png, "wide.png").unwrap_err().to_string().contains("wide.png"));
}
