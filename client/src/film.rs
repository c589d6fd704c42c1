//! Exact films on the client: the f64 sums a server streams pass by pass (FilmTile events),
//! kept, saved and merged so that slices of a render's samples, or a checkpoint and the
//! render resumed from it, add up to the single render's image bit for bit.
//!
//! Floating-point addition is not associative, so exactness comes from doing the additions
//! in one order everywhere: a pixel's total is the sum of its whole passes' sums, added in
//! sample order (`render_core::film::TileFilm::absorb`), whether the passes were rendered in
//! one process, on several machines, or before and after a crash.

use std::io::{Read, Write};
use std::ops::Range;
use std::path::Path;

use anyhow::{Context, Result, bail};
use render_core::film::{Aov, Rect, TileFilm};
use tessera_proto::v1 as pb;

use crate::output::{Image, TileRect};

const MAGIC: &[u8; 8] = b"TSRFILM1";

/// A film of samples `range` of every pixel of a `width`×`height` image.
#[derive(Clone, Debug)]
pub struct ExactFilm {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// The samples held: `range.start` is where the slice began, `range.end` the last
    /// completed pass's end.
    pub range: Range<u32>,
    /// Header attributes the final EXR carries (scene, settings hash, AOVs asked for).
    pub metadata: Vec<(String, String)>,
    /// A slice's whole passes, each its own sums; a film that starts at sample 0 keeps one
    /// entry, the running total (adding a pass to it is what the single render does).
    passes: Vec<(Range<u32>, TileFilm)>,
}

impl ExactFilm {
    /// An empty film whose samples start at `first`.
    pub fn new(width: u32, height: u32, first: u32) -> Self {
        ExactFilm { width, height, range: first..first, metadata: Vec::new(), passes: Vec::new() }
    }

    fn whole(&self) -> Rect {
        Rect { x: 0, y: 0, width: self.width, height: self.height }
    }

    /// Adds one tile's pass sums from the stream.
    pub fn add(&mut self, t: &pb::FilmTile) -> Result<()> {
        let rect = Rect { x: t.x, y: t.y, width: t.width, height: t.height };
        if t.x.checked_add(t.width).is_none_or(|r| r > self.width) || t.y.checked_add(t.height).is_none_or(|b| b > self.height) {
            bail!("film tile {rect:?} lies outside the {}x{} image", self.width, self.height);
        }
        let pass = TileFilm::decode(rect, t.extra, t.end_sample, &t.sums)
            .with_context(|| format!("film tile {rect:?} of pass {} is malformed", t.pass_index))?;
        let samples = t.first_sample..t.end_sample;
        let whole = self.whole();
        let running = self.range.start == 0;
        let fresh = match self.passes.last() {
            None => true,
            // A film from sample 0 adds every pass into its one total.
            Some(_) if running => false,
            Some((r, _)) => *r != samples,
        };
        if fresh {
            self.passes.push((samples, TileFilm::new(whole, t.extra)));
        }
        let (_, film) = self.passes.last_mut().expect("pushed above");
        if film.has_extra() != t.extra {
            bail!("film tile {rect:?} carries other AOV sums than the film it adds to");
        }
        film.absorb(&pass);
        Ok(())
    }

    /// Marks the samples up to `end` complete (a pass finished: all its tiles arrived).
    pub fn pass_done(&mut self, end: u32) {
        self.range.end = end;
        if let Some((r, film)) = self.passes.last_mut() {
            r.end = end;
            film.samples = end;
        }
    }

    /// Forgets everything (the render restarted on a changed scene).
    pub fn clear(&mut self) {
        self.passes.clear();
        self.range.end = self.range.start;
    }

    /// The image of a film that starts at sample 0: every AOV in `aovs`, resolved exactly as
    /// the server resolves its tiles.
    pub fn resolve(&self, aovs: &[String]) -> Result<Image> {
        if self.range.start != 0 {
            bail!("samples {:?} alone are not an image: merge the slice with those before it", self.range);
        }
        let mut image = Image { width: self.width, height: self.height, ..Default::default() };
        let empty = TileFilm::new(self.whole(), false);
        let total = self.passes.first().map_or(&empty, |(_, f)| f);
        for name in aovs {
            let aov = Aov::from_name(name).with_context(|| format!("unknown AOV {name}"))?;
            let whole = TileRect { x: 0, y: 0, width: self.width, height: self.height };
            image.write_tile(name, whole, aov.channels() as u32, &total.resolve(aov));
        }
        Ok(image)
    }

    /// Adds `later`, the slice that starts where this film ends, pass by pass.
    pub fn append(&mut self, later: &ExactFilm) -> Result<()> {
        if (later.width, later.height) != (self.width, self.height) {
            bail!("a {}x{} slice cannot follow a {}x{} one", later.width, later.height, self.width, self.height);
        }
        if later.range.start != self.range.end {
            bail!("samples {:?} do not follow samples {:?}", later.range, self.range);
        }
        for (r, pass) in &later.passes {
            match self.passes.first_mut() {
                Some((total, film)) if self.range.start == 0 => {
                    film.absorb(pass);
                    total.end = r.end;
                }
                _ => self.passes.push((r.clone(), pass.clone())),
            }
        }
        self.range.end = later.range.end;
        Ok(())
    }

    /// Writes the film to `path` (the caller makes the write atomic).
    pub fn save(&self, path: &Path) -> Result<()> {
        let header = serde_json::json!({
            "width": self.width,
            "height": self.height,
            "range": [self.range.start, self.range.end],
            "metadata": self.metadata,
            "passes": self.passes.iter().map(|(r, f)| serde_json::json!({"range": [r.start, r.end], "extra": f.has_extra()})).collect::<Vec<_>>(),
        })
        .to_string();
        let mut out = std::io::BufWriter::new(std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?);
        out.write_all(MAGIC)?;
        out.write_all(&(header.len() as u64).to_le_bytes())?;
        out.write_all(header.as_bytes())?;
        for (_, film) in &self.passes {
            out.write_all(&film.encode())?;
        }
        out.into_inner().map_err(|e| e.into_error())?.sync_all()?;
        Ok(())
    }

    /// Reads a film [`Self::save`] wrote.
    pub fn load(path: &Path) -> Result<ExactFilm> {
        let bad = |why: &str| anyhow::anyhow!("{}: not a Tessera film ({why})", path.display());
        let mut file = std::io::BufReader::new(std::fs::File::open(path).with_context(|| format!("cannot open {}", path.display()))?);
        let mut magic = [0u8; 8];
        file.read_exact(&mut magic).map_err(|_| bad("too short"))?;
        if &magic != MAGIC {
            return Err(bad("wrong magic"));
        }
        let mut len = [0u8; 8];
        file.read_exact(&mut len)?;
        let len = u64::from_le_bytes(len);
        if len > 1 << 26 {
            return Err(bad("header too large"));
        }
        let mut header = vec![0u8; len as usize];
        file.read_exact(&mut header).map_err(|_| bad("truncated header"))?;
        let h: serde_json::Value = serde_json::from_slice(&header).map_err(|_| bad("header is not JSON"))?;
        let num = |v: &serde_json::Value| v.as_u64().and_then(|n| u32::try_from(n).ok()).ok_or_else(|| bad("a number is missing"));
        let (width, height) = (num(&h["width"])?, num(&h["height"])?);
        let mut film = ExactFilm::new(width, height, num(&h["range"][0])?);
        film.range.end = num(&h["range"][1])?;
        film.metadata = serde_json::from_value(h["metadata"].clone()).map_err(|_| bad("metadata"))?;
        let whole = film.whole();
        for p in h["passes"].as_array().ok_or_else(|| bad("no passes"))? {
            let extra = p["extra"].as_bool().ok_or_else(|| bad("pass without extra"))?;
            let range = num(&p["range"][0])?..num(&p["range"][1])?;
            let n = width as usize * height as usize * TileFilm::encoded_bytes_per_pixel(extra);
            let mut bytes = vec![0u8; n];
            file.read_exact(&mut bytes).map_err(|_| bad("truncated sums"))?;
            let sums = TileFilm::decode(whole, extra, range.end, &bytes).ok_or_else(|| bad("damaged sums"))?;
            film.passes.push((range, sums));
        }
        Ok(film)
    }

    /// One film from slices that together cover samples 0 to their last one, in any order.
    pub fn merge(mut parts: Vec<ExactFilm>) -> Result<ExactFilm> {
        parts.sort_by_key(|p| p.range.start);
        let mut parts = parts.into_iter();
        let mut merged = parts.next().context("nothing to merge")?;
        if merged.range.start != 0 {
            bail!("no slice starts at sample 0 (the first starts at {})", merged.range.start);
        }
        for part in parts {
            if part.metadata_value("settingsHash") != merged.metadata_value("settingsHash") {
                bail!("slices of different renders (their settings hashes differ)");
            }
            merged.append(&part)?;
        }
        Ok(merged)
    }

    /// The image's noise estimate (relative standard error of its mean luminance, as the
    /// server's `Progress` reports it) and mean samples per pixel, from a film that starts
    /// at sample 0.
    pub fn noise_and_mean_spp(&self) -> Option<(f64, f64)> {
        let (_, total) = self.passes.first().filter(|_| self.range.start == 0)?;
        let pixels = (self.width as f64 * self.height as f64).max(1.0);
        let (var, mean) = total.noise_terms();
        Some((render_core::render::relative_noise(var, mean, pixels), total.sample_totals().1 as f64 / pixels))
    }

    /// A header attribute.
    pub fn metadata_value(&self, key: &str) -> Option<&str> {
        self.metadata.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }
}
