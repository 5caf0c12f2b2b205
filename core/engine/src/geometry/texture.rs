//! Float RGB textures: bilinear lookup, repeat wrap, Blender's UV convention
//! (v = 0 at the bottom row).

use crate::scene::ImageRef;
use crate::Rgb;

/// An inline RGB image, ready for lookups.
#[derive(Clone, Debug)]
pub struct Texture {
    width: usize,
    height: usize,
    rgb: Vec<f32>,
}

impl Texture {
    /// From a validated inline image (`None` for an unresolved path).
    pub fn from_ref(img: &ImageRef) -> Option<Texture> {
        match img {
            ImageRef::Inline { width, height, rgb } => Some(Texture {
                width: *width as usize,
                height: *height as usize,
                rgb: rgb.clone(),
            }),
            ImageRef::Path { .. } => None,
        }
    }

    /// Width and height.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Texel (`x`, `y`), `y` counted from the top row, wrapped.
    #[inline]
    pub fn texel(&self, x: isize, y: isize) -> Rgb {
        let x = x.rem_euclid(self.width as isize) as usize;
        let y = y.rem_euclid(self.height as isize) as usize;
        let i = 3 * (y * self.width + x);
        Rgb::new(self.rgb[i], self.rgb[i + 1], self.rgb[i + 2])
    }

    /// Bilinear lookup at texture coordinates (`u`, `v`), v up, repeat wrap.
    pub fn lookup(&self, u: f32, v: f32) -> Rgb {
        let x = u * self.width as f32 - 0.5;
        let y = (1.0 - v) * self.height as f32 - 0.5;
        if !x.is_finite() || !y.is_finite() {
            return self.texel(0, 0);
        }
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as isize, y0 as isize);
        let a = self.texel(x0, y0).lerp(self.texel(x0 + 1, y0), fx);
        let b = self.texel(x0, y0 + 1).lerp(self.texel(x0 + 1, y0 + 1), fx);
        a.lerp(b, fy)
    }
}
