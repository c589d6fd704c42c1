//! Quality presets (`--quality`): named settings of the knobs whose price
//! `tessera bench accuracy` measures (`docs/accuracy-vs-time.md` lists the error and time
//! each reached on the Cornell box).

/// A named preset.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Quality {
    /// Blocking out: a noisy but complete image in a blink.
    Draft,
    /// Look development (the default).
    Preview,
    /// Frames for delivery.
    Final,
    /// Ground truth for tests and comparisons: every approximation off, many samples.
    Reference,
}

/// What a preset sets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Preset {
    /// Samples per pixel.
    pub spp: u32,
    /// Scattering events.
    pub max_depth: u32,
    /// Firefly clamp.
    pub clamp: Option<f32>,
}

impl Quality {
    /// Every preset, cheapest first.
    pub const ALL: [Quality; 4] = [Quality::Draft, Quality::Preview, Quality::Final, Quality::Reference];

    /// The preset's settings. On the Cornell box at 64 spp the error stops falling past 5
    /// bounces (the report's depth sweep); the deeper presets leave room for scenes that
    /// bounce light further (glass, bright interiors). No preset clamps: the clamp's bias
    /// outweighed its variance gain at every setting measured.
    pub fn preset(self) -> Preset {
        match self {
            Quality::Draft => Preset { spp: 16, max_depth: 4, clamp: None },
            Quality::Preview => Preset { spp: 64, max_depth: 8, clamp: None },
            Quality::Final => Preset { spp: 512, max_depth: 16, clamp: None },
            Quality::Reference => Preset { spp: 4096, max_depth: 64, clamp: None },
        }
    }

    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Quality::Draft => "draft",
            Quality::Preview => "preview",
            Quality::Final => "final",
            Quality::Reference => "reference",
        }
    }

    /// The presets as a markdown table.
    pub fn table() -> String {
        let mut s = String::from("| preset | spp | max depth | clamp |\n| --- | ---: | ---: | --- |\n");
        for q in Self::ALL {
            let p = q.preset();
            s += &format!("| {} | {} | {} | {} |\n", q.name(), p.spp, p.max_depth, p.clamp.map_or("off".into(), |c| c.to_string()));
        }
        s
    }
}
