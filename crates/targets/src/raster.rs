//! The grey raster every decoder writes and the detector reads, and what the decoders
//! share: the size limits, the zeroed (huge-page) buffer, the 8- and 16-bit grey tables and
//! the fast paths' "not decoded here" answer. It sits below [`image_io`](crate::image_io)
//! and its fast paths ([`tiff_strips`](crate::tiff_strips), [`png_rows`](crate::png_rows)),
//! which all use it and none of which it uses.

/// A grey image, row-major, values nominally in [0, 1] (1 = white).
#[derive(Clone, Debug)]
pub struct GrayImage {
    /// Width, pixels (columns).
    pub width: usize,
    /// Height, pixels (rows).
    pub height: usize,
    /// The `width · height` values, row after row from the top: pixel (x, y) is at
    /// `y · width + x`.
    pub data: Vec<f32>,
}

impl GrayImage {
    /// An image filled with `value`.
    pub fn new(width: usize, height: usize, value: f32) -> Self {
        GrayImage {
            width,
            height,
            data: vec![value; width * height],
        }
    }

    /// Pixel value at integer coordinates (no bounds check beyond the slice's own).
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> f32 {
        self.data[y * self.width + x]
    }

    /// Bilinear interpolation at (x, y), pixel centres at integer coordinates.
    /// Outside the image the nearest border value is used.
    #[inline(always)]
    pub fn sample(&self, x: f64, y: f64) -> f32 {
        let w = self.width as isize;
        let h = self.height as isize;
        if w == 0 || h == 0 || !x.is_finite() || !y.is_finite() {
            return 0.0;
        }
        // floor() without a libm call (the baseline x86-64 target has no SSE4.1 rounding).
        let xt = x as isize;
        let yt = y as isize;
        let xi = xt - ((xt as f64) > x) as isize;
        let yi = yt - ((yt as f64) > y) as isize;
        let fx = (x - xi as f64) as f32;
        let fy = (y - yi as f64) as f32;
        if xi >= 0 && yi >= 0 && xi + 1 < w && yi + 1 < h {
            let i = yi as usize * self.width + xi as usize;
            let a = self.data[i];
            let b = self.data[i + 1];
            let c = self.data[i + self.width];
            let d = self.data[i + self.width + 1];
            let top = a + (b - a) * fx;
            let bot = c + (d - c) * fx;
            return top + (bot - top) * fy;
        }
        let x0 = xi.clamp(0, w - 1) as usize;
        let y0 = yi.clamp(0, h - 1) as usize;
        let x1 = (xi + 1).clamp(0, w - 1) as usize;
        let y1 = (yi + 1).clamp(0, h - 1) as usize;
        let a = self.get(x0, y0);
        let b = self.get(x1, y0);
        let c = self.get(x0, y1);
        let d = self.get(x1, y1);
        let top = a + (b - a) * fx;
        let bot = c + (d - c) * fx;
        top + (bot - top) * fy
    }

    /// [`GrayImage::sample`] for points the caller knows to be inside the image (at least a
    /// pixel from the right and bottom edges): no border handling, no `floor` fix-up (the
    /// coordinates are non-negative). The same value as `sample` bit for bit; a point that is
    /// not inside after all goes the general way.
    #[inline(always)]
    pub fn sample_inside(&self, x: f64, y: f64) -> f32 {
        // `as i64` saturates (NaN → 0), so the test below is exact; signed conversions both
        // ways are single instructions on x86-64, unsigned ones are not.
        let (xt, yt) = (x as i64, y as i64);
        let (w1, h1) = (self.width as i64 - 1, self.height as i64 - 1);
        if x >= 0.0 && y >= 0.0 && xt < w1 && yt < h1 {
            let fx = (x - xt as f64) as f32;
            let fy = (y - yt as f64) as f32;
            let (xi, yi) = (xt as usize, yt as usize);
            let i = yi * self.width + xi;
            let r0 = &self.data[i..i + 2];
            let r1 = &self.data[i + self.width..i + self.width + 2];
            let top = r0[0] + (r0[1] - r0[0]) * fx;
            let bot = r1[0] + (r1[1] - r1[0]) * fx;
            top + (bot - top) * fy
        } else {
            self.sample(x, y)
        }
    }

    /// True when (x, y) is inside the image with `margin` pixels to spare.
    #[inline]
    pub fn inside(&self, x: f64, y: f64, margin: f64) -> bool {
        x >= margin
            && y >= margin
            && x <= self.width as f64 - 1.0 - margin
            && y <= self.height as f64 - 1.0 - margin
    }
}

/// Largest image side accepted (pixels) and largest decoder allocation (bytes).
pub(crate) const MAX_SIDE: u32 = 40_000;
pub(crate) const MAX_ALLOC: u64 = 1 << 30;

/// `n` zeros, for an image to be written: a big buffer goes in memory the kernel is asked to
/// back with 2 MB pages. The pages of a fresh allocation are only mapped when first written,
/// one page fault each, and on 4 kB pages that was the most expensive part of decoding a big
/// image: writing a fresh 96 MB buffer (a 24-megapixel `f32` image) takes 33 ms of one thread
/// in page faults, 5 ms on 2 MB pages (Linux 6.18 in a VM, transparent huge pages on
/// `madvise`); written from two threads at once, the 4 kB faults take no less time.
pub(crate) fn zeroed_f32(n: usize) -> Vec<f32> {
    let mut v = vec![0.0f32; n];
    advise_huge_pages(&mut v);
    v
}

/// Asks the kernel to back `buf` with huge pages where it covers whole 2 MB pages (a hint,
/// which changes neither the contents nor their addresses; nothing elsewhere).
#[cfg(target_os = "linux")]
fn advise_huge_pages<T>(buf: &mut [T]) {
    const HUGE: usize = 2 << 20;
    let start = buf.as_mut_ptr() as usize;
    let end = start + std::mem::size_of_val(buf);
    let first = start.next_multiple_of(HUGE);
    let last = end - end % HUGE;
    if first < last {
        // SAFETY: the range lies inside `buf`, which we borrow mutably, and is page aligned;
        // MADV_HUGEPAGE only tells the kernel which page size to use for it and leaves the
        // memory as it is. A failure (no transparent huge pages) changes nothing.
        unsafe {
            libc::madvise(
                first as *mut libc::c_void,
                last - first,
                libc::MADV_HUGEPAGE,
            );
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise_huge_pages<T>(_buf: &mut [T]) {}

/// Grey value of every 8-bit (16-bit) level as `to_luma32f` gives it, non-finite values as 0.
pub(crate) fn lut_u8() -> &'static [f32] {
    static LUT: std::sync::OnceLock<Vec<f32>> = std::sync::OnceLock::new();
    LUT.get_or_init(|| {
        let b = image::GrayImage::from_fn(256, 1, |x, _| image::Luma([x as u8]));
        finite(image::DynamicImage::ImageLuma8(b).to_luma32f().into_raw())
    })
}

pub(crate) fn lut_u16() -> &'static [f32] {
    static LUT: std::sync::OnceLock<Vec<f32>> = std::sync::OnceLock::new();
    LUT.get_or_init(|| {
        let b = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(65536, 1, |x, _| {
            image::Luma([x as u16])
        });
        finite(image::DynamicImage::ImageLuma16(b).to_luma32f().into_raw())
    })
}

fn finite(mut v: Vec<f32>) -> Vec<f32> {
    for x in &mut v {
        if !x.is_finite() {
            *x = 0.0;
        }
    }
    v
}

/// Why a fast path ([`decode_grey_strips`](crate::tiff_strips::decode_grey_strips), [`decode_grey_png`](crate::png_rows::decode_grey_png)) did not decode a file. Either way [`decode_image`](crate::decode_image)
/// then runs the general decoder.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum NotDecoded {
    /// Not a layout this path handles.
    Unsupported(String),
    /// A damaged file (what is wrong).
    Corrupt(String),
}

impl std::fmt::Display for NotDecoded {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NotDecoded::Unsupported(s) => write!(f, "not handled here: {s}"),
            NotDecoded::Corrupt(s) => write!(f, "corrupt: {s}"),
        }
    }
}

/// The channels of one image, each a [`GrayImage`] of the same size (1 for grey, 3 for
/// colour).
#[derive(Clone, Debug)]
pub struct ColourImage {
    /// The channels, each `width × height`.
    pub planes: Vec<GrayImage>,
}

impl ColourImage {
    /// A grey image as one channel.
    pub fn grey(img: GrayImage) -> Self {
        ColourImage { planes: vec![img] }
    }

    /// Width, px.
    pub fn width(&self) -> usize {
        self.planes.first().map_or(0, |p| p.width)
    }

    /// Height, px.
    pub fn height(&self) -> usize {
        self.planes.first().map_or(0, |p| p.height)
    }

    /// The mean of the channels.
    pub fn luminance(&self) -> GrayImage {
        let (w, h) = (self.width(), self.height());
        let mut out = GrayImage::new(w, h, 0.0);
        let k = 1.0 / self.planes.len().max(1) as f32;
        for p in &self.planes {
            for (o, v) in out.data.iter_mut().zip(&p.data) {
                *o += v * k;
            }
        }
        out
    }
}
