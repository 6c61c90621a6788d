//! PNG copies of the SVG figures, on request (`--png`): each SVG rasterized by resvg with
//! the text set in DejaVu Sans, whose font file is compiled into legwork (the `dejavu`
//! crate), so the PNGs look the same on every machine and no system font library is read.
//!
//! ```no_run
//! let pngs = legwork::viz::png::write_pngs(&["plots/cost.svg".into()], 2.0).unwrap();
//! assert_eq!(pngs[0], std::path::Path::new("plots/cost.png"));
//! ```

use super::VizError;
use resvg::usvg;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

/// The fonts the figures are drawn with: DejaVu Sans (regular, bold, oblique) as every
/// generic family.
fn fonts() -> Arc<usvg::fontdb::Database> {
    static FONTS: OnceLock<Arc<usvg::fontdb::Database>> = OnceLock::new();
    FONTS
        .get_or_init(|| {
            let mut db = usvg::fontdb::Database::new();
            for face in [dejavu::sans::regular(), dejavu::sans::bold(), dejavu::sans::oblique(), dejavu::sans::bold_oblique()] {
                db.load_font_data(face.to_vec());
            }
            db.set_sans_serif_family("DejaVu Sans");
            db.set_serif_family("DejaVu Sans");
            db.set_monospace_family("DejaVu Sans");
            Arc::new(db)
        })
        .clone()
}

/// The PNG of the SVG text `svg` at `scale` times its size (pixels per SVG unit).
pub fn svg_png(svg: &str, scale: f32, origin: &str) -> Result<Vec<u8>, VizError> {
    let bad = |message: String| VizError::Plot { path: origin.to_string(), message };
    if !(scale.is_finite() && scale > 0.0 && scale <= 8.0) {
        return Err(bad(format!("PNG scale: expected 0-8, got {scale}")));
    }
    let options = usvg::Options { font_family: "DejaVu Sans".into(), fontdb: fonts(), ..usvg::Options::default() };
    let tree = usvg::Tree::from_str(svg, &options).map_err(|e| bad(format!("cannot read the SVG: {e}")))?;
    let size = tree.size().to_int_size().scale_by(scale).ok_or_else(|| bad("the figure has no size".into()))?;
    let mut pixmap = resvg::tiny_skia::Pixmap::new(size.width(), size.height()).ok_or_else(|| bad(format!("cannot allocate {} x {} pixels", size.width(), size.height())))?;
    resvg::render(&tree, resvg::tiny_skia::Transform::from_scale(scale, scale), &mut pixmap.as_mut());
    pixmap.encode_png().map_err(|e| bad(format!("cannot encode the PNG: {e}")))
}

/// Writes a PNG beside each SVG file (`cost.svg` -> `cost.png`) at `scale`; returns the PNGs.
pub fn write_pngs(svgs: &[PathBuf], scale: f32) -> Result<Vec<PathBuf>, VizError> {
    svgs.iter()
        .filter(|p| p.extension().is_some_and(|e| e == "svg"))
        .map(|svg| {
            let text = std::fs::read_to_string(svg).map_err(|e| VizError::io(svg, e))?;
            let png = svg.with_extension("png");
            std::fs::write(&png, svg_png(&text, scale, &svg.display().to_string())?).map_err(|e| VizError::io(&png, e))?;
            Ok(png)
        })
        .collect()
}

/// The SVG files in `dir` (sorted), for [`write_pngs`].
pub fn svgs_in(dir: &Path) -> Vec<PathBuf> {
    let mut svgs: Vec<PathBuf> = std::fs::read_dir(dir).map(|entries| entries.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.extension().is_some_and(|e| e == "svg")).collect()).unwrap_or_default();
    svgs.sort();
    svgs
}

/// The scale of the PNGs the commands write: 2 pixels per SVG unit (a 960-unit figure is
/// 1920 pixels wide).
pub const PNG_SCALE: f32 = 2.0;
