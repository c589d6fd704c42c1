//! UDIM texture sets (`tex.<UDIM>.png`): one file per unit square of texture space, found
//! next to the layer that authored the set, as USD's `UsdShadeUdimUtils` finds them. MaterialX
//! documents may name the same squares Mudbox's way (`tex.<UVTILE>.png`, `u1_v1` for 1001).

use openusd::ar::Resolver;
use render_core::material::{ParamValue, UDIM_TILES};

use super::Reader;

/// Where a UDIM set's path holds its tile number.
pub(super) const UDIM_TOKEN: &str = "<UDIM>";

/// Where a set named Mudbox's way holds its tile's column and row, from 1 (MaterialX's
/// `filename` token): `u1_v1` is tile 1001, `u2_v1` 1002, `u1_v2` 1011.
pub(super) const UVTILE_TOKEN: &str = "<UVTILE>";

/// True when `path` names a set of tiles rather than one file.
pub(super) fn names_tiles(path: &str) -> bool {
    path.contains(UDIM_TOKEN) || path.contains(UVTILE_TOKEN)
}

/// The file of tile `tile` (1001-based) of the set at `resolved`.
fn tile_path(resolved: &str, tile: u16) -> String {
    let square = tile - 1001;
    let uvtile = format!("u{}_v{}", square % 10 + 1, square / 10 + 1);
    resolved.replacen(UDIM_TOKEN, &tile.to_string(), 1).replacen(UVTILE_TOKEN, &uvtile, 1)
}

/// The tiles of the set at `resolved` (a path holding [`UDIM_TOKEN`] or [`UVTILE_TOKEN`])
/// that exist, each with its bytes or the error reading them.
fn read_tiles(resolved: &str) -> Vec<(u16, String, std::io::Result<Vec<u8>>)> {
    let resolver = openusd::ar::DefaultResolver::new();
    UDIM_TILES
        .filter_map(|tile| {
            let path = tile_path(resolved, tile);
            let opened = resolver.open_asset(&openusd::ar::ResolvedPath::new(std::path::PathBuf::from(&path)));
            let bytes = match opened {
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => return None,
                Err(e) => Err(e),
                Ok(mut asset) => {
                    let mut bytes = Vec::new();
                    std::io::Read::read_to_end(&mut asset, &mut bytes).map(|_| bytes)
                }
            };
            Some((tile, path, bytes))
        })
        .collect()
}

/// Tiles 1101 to 1999 of the set at `resolved` that exist: texture space beyond the ten
/// columns and rows USD reads, which a painting tool may still have written.
fn tiles_past_the_last(resolved: &str) -> Vec<u16> {
    if !resolved.contains(UDIM_TOKEN) {
        return Vec::new();
    }
    (UDIM_TILES.end() + 1..=1999).filter(|&tile| std::path::Path::new(&tile_path(resolved, tile)).exists()).collect()
}

impl Reader<'_> {
    /// A UDIM asset input of a shader, its tiles found next to the layer that authored it
    /// ([`Self::udim_tiles`]); lookups where no tile is take the node's fallback.
    pub(super) fn udim_param(&mut self, node: &str, input: &str, a: &openusd::sdf::AssetPath) -> ParamValue {
        let source = a.as_str().to_string();
        let Some(resolved) = a.resolved_path().filter(|r| r.contains(UDIM_TOKEN)) else {
            self.out.warnings.push(format!(
                "{node}: input '{input}': no tile of UDIM texture '{source}' ({}-{}) is next to the layer that authored it",
                UDIM_TILES.start(),
                UDIM_TILES.end()
            ));
            return ParamValue::Asset(source);
        };
        self.out.texture_paths.push((format!("{node}.inputs:{input}"), resolved.to_string()));
        self.udim_tiles(node, input, &source, resolved)
    }

    /// The tiles of the UDIM set `source` found at `resolved`, each read and kept for upload
    /// (a tile that cannot be read is reported and left out), or the authored path with a
    /// warning when there is none.
    pub(super) fn udim_tiles(&mut self, node: &str, input: &str, source: &str, resolved: &str) -> ParamValue {
        let beyond = tiles_past_the_last(resolved);
        if !beyond.is_empty() {
            self.out.warnings.push(format!(
                "{node}: input '{input}': UDIM texture '{source}' has tiles past {} ({}), which are not read (USD reads none either)",
                UDIM_TILES.end(),
                beyond.iter().map(u16::to_string).collect::<Vec<_>>().join(", ")
            ));
        }
        let mut tiles = Vec::new();
        for (tile, path, bytes) in read_tiles(resolved) {
            if let ParamValue::Texture { hash, .. } = self.keep_texture(node, input, &path, bytes) {
                tiles.push((tile, hash));
            }
        }
        if tiles.is_empty() {
            self.out.warnings.push(format!("{node}: input '{input}': UDIM texture '{source}' has no tile that could be read"));
            return ParamValue::Asset(source.to_string());
        }
        ParamValue::Udim { tiles, source: source.to_string() }
    }
}
