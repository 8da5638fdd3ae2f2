//! A Ward material as glTF 2.0: the mapping onto glTF's metallic-roughness model (with
//! `KHR_materials_ior` where the plain model cannot hold the Ward parameters), and a sphere
//! asset carrying it, self-contained (one `.gltf` file).
//!
//! **The mapping** (its error, rendered by Blender's Cycles and by glTF's own BRDF under the
//! light probes: docs/accuracy.md). glTF's specular lobe is GGX with a Fresnel term that
//! rises to 1 at grazing angles; Ward's is a Gaussian of slope with a constant weight ρs. No
//! renderer can be given Ward's constant weight: a dielectric's Fresnel term is set by its
//! index of refraction alone (Blender turns `KHR_materials_specular`'s `specularFactor` into
//! a smaller index, keeping the rise to 1, where glTF's viewers scale the rise too; an index
//! below 1 makes Blender draw total internal reflection, a mirror). So:
//!
//! * roughness: GGX's α = roughness². GGX and Ward's Gaussian agree at their peak for the
//!   same α, but GGX's tails hold more of the light, so the same α looks broader under a
//!   sun; `roughness = √(0.7 α)` ([`GGX_ALPHA_SCALE`], the scale of 0.4–1.3 that
//!   differed least from Ward's highlights under the probes) and 0 for the ideal mirror;
//! * a dielectric (ρs > 0) has glTF's neutral specular and the index of refraction whose
//!   normal-incidence reflectance F0 makes the specular part as bright as Ward's over the
//!   sphere's disc: the centre gets F0 < ρs, the rim (where the exact Fresnel term rises)
//!   more, and `(1 − w) F0 + w F̄(F0) = ρs`, F̄ the disc mean of the exact Fresnel term and
//!   w = [`GRAZING_LIGHT`] the share of the rise that real light gives (grazing reflections
//!   see the horizon and the ground, darker than the sky: measured under the probes).
//!   glTF weights the diffuse by 1 − F, so `baseColor = ρd / (1 − F0)` keeps the centre's
//!   diffuse at ρd. Without a specular part (ρs = 0), `KHR_materials_specular`'s
//!   `specularFactor` 0, which every renderer reads as no reflection at all;
//! * a material whose diffuse part is under a tenth of its specular one is a metal
//!   (`metallic` 1), which every glTF viewer draws without extensions: its Fresnel term
//!   rises to 1 at grazing angles, so `baseColor` is the F0 whose mean over a sphere's disc
//!   is ρs. Over the disc cos θ = √(1 − ρ²) with ρ² uniform, so the mean of (1 − cos θ)⁵ is
//!   1/21 and F0 = (ρs − 1/21) / (1 − 1/21); ρd is dropped.

use super::{Material, Ward};
use serde_json::{Value, json};

/// Over a sphere's disc, the mean of Schlick's (1 − cos θ)⁵.
pub const DISC_FRESNEL_WEIGHT: f64 = 1.0 / 21.0;
/// Below this ratio ρd / ρs the material is exported as a metal.
pub const METAL_RATIO: f64 = 0.1;
/// GGX's α over Ward's: what differs least under the light probes (docs/accuracy.md).
pub const GGX_ALPHA_SCALE: f64 = 0.7;
/// glTF's index of refraction when `KHR_materials_ior` is absent.
pub const DEFAULT_IOR: f64 = 1.5;
/// The share of a uniform light's Fresnel rise that real light gives a sphere's rim: the
/// least-squares fit of Blender's disc brightness over six dielectrics × five F0 under 11
/// probes (docs/accuracy.md, "The glTF export").
pub const GRAZING_LIGHT: f64 = 0.55;
/// The disc whose brightness is matched, in radii: the outermost 2 % straddle the outline.
pub const DISC_EDGE: f64 = 0.98;

/// The glTF metallic-roughness parameters of a Ward material (grey: one value per colour
/// channel).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pbr {
    /// `baseColorFactor`'s grey value, in [0, 1] (a colour tints it).
    pub base_color: f64,
    /// `metallicFactor`, 0 or 1.
    pub metallic: f64,
    /// `roughnessFactor`, in [0, 1].
    pub roughness: f64,
    /// `KHR_materials_ior` (≥ 1; 1.5 is glTF's default, and the extension is then left out).
    pub ior: f64,
    /// `KHR_materials_specular`'s `specularFactor`: 1 (left out), or 0 for no reflection.
    pub specular: f64,
}

/// The metal F0 whose mean over a sphere's disc is `rho_s`.
fn metal_f0(rho_s: f64) -> f64 {
    let w = DISC_FRESNEL_WEIGHT;
    ((rho_s - w) / (1.0 - w)).clamp(0.0, 1.0)
}

/// The exact Fresnel reflectance of unpolarized light at incidence cos θ on a dielectric of
/// relative index `eta` ≥ 1 (what Cycles uses).
pub fn fresnel_dielectric(cos: f64, eta: f64) -> f64 {
    let c = cos.clamp(0.0, 1.0);
    let g2 = eta * eta - 1.0 + c * c;
    let g = g2.max(0.0).sqrt();
    let (a, b) = (g - c, g + c);
    if b == 0.0 {
        return 1.0;
    }
    let r = 0.5 * (a / b).powi(2);
    let m = (c * b - 1.0) / (c * a + 1.0);
    r * (1.0 + m * m)
}

/// The index of refraction whose normal-incidence reflectance is `f0`.
pub fn ior_of_f0(f0: f64) -> f64 {
    let s = f0.clamp(0.0, 0.99).sqrt();
    (1.0 + s) / (1.0 - s)
}

/// The mean of the exact Fresnel term over a sphere's disc (ρ ≤ [`DISC_EDGE`]) seen
/// orthographically, where a mirror reflection has cos θ = √(1 − ρ²).
pub fn disc_fresnel(f0: f64) -> f64 {
    const N: usize = 512;
    let eta = ior_of_f0(f0);
    let edge = DISC_EDGE * DISC_EDGE;
    (0..N)
        .map(|i| {
            let u = edge * (i as f64 + 0.5) / N as f64;
            fresnel_dielectric((1.0 - u).sqrt(), eta)
        })
        .sum::<f64>()
        / N as f64
}

/// The dielectric F0 whose specular part is, over the disc and under real light, as bright
/// as Ward's of weight `rho_s`: `(1 − w) F0 + w F̄(F0) = ρs` (see the module's text).
pub fn dielectric_f0(rho_s: f64) -> f64 {
    let w = GRAZING_LIGHT;
    let brightness = |f0: f64| (1.0 - w) * f0 + w * disc_fresnel(f0);
    // Monotone in F0, 0 at 0; beyond ρs for every valid material (ρd + ρs ≤ 1).
    let (mut low, mut high) = (0.0, 0.99);
    for _ in 0..48 {
        let mid = 0.5 * (low + high);
        if brightness(mid) < rho_s {
            low = mid;
        } else {
            high = mid;
        }
    }
    0.5 * (low + high)
}

/// The mapping of (ρd, ρs, α) onto glTF's model (see the module's documentation).
pub fn pbr_of(ward: &Ward) -> Pbr {
    let (rho_d, rho_s) = (ward.rho_d.clamp(0.0, 1.0), ward.rho_s.clamp(0.0, 1.0));
    let roughness = (GGX_ALPHA_SCALE * ward.alpha.clamp(0.0, 1.0)).sqrt();
    if rho_s > 0.0 && rho_d < METAL_RATIO * rho_s {
        return Pbr {
            base_color: metal_f0(rho_s),
            metallic: 1.0,
            roughness,
            ior: DEFAULT_IOR,
            specular: 1.0,
        };
    }
    if rho_s == 0.0 {
        return Pbr {
            base_color: rho_d,
            metallic: 0.0,
            roughness,
            ior: DEFAULT_IOR,
            specular: 0.0,
        };
    }
    let f0 = dielectric_f0(rho_s);
    Pbr {
        base_color: (rho_d / (1.0 - f0)).min(1.0),
        metallic: 0.0,
        roughness,
        ior: ior_of_f0(f0),
        specular: 1.0,
    }
}

/// A UV sphere of unit radius: (positions, normals, indices).
fn sphere_mesh(rings: u32, segments: u32) -> (Vec<[f32; 3]>, Vec<u16>) {
    let mut positions = Vec::new();
    for ring in 0..=rings {
        let theta = std::f64::consts::PI * f64::from(ring) / f64::from(rings);
        for segment in 0..=segments {
            let phi = 2.0 * std::f64::consts::PI * f64::from(segment) / f64::from(segments);
            positions.push([
                (theta.sin() * phi.cos()) as f32,
                theta.cos() as f32,
                (theta.sin() * phi.sin()) as f32,
            ]);
        }
    }
    let row = segments + 1;
    let mut indices = Vec::new();
    for ring in 0..rings {
        for segment in 0..segments {
            let a = (ring * row + segment) as u16;
            let b = a + row as u16;
            indices.extend_from_slice(&[a, a + 1, b, a + 1, b + 1, b]);
        }
    }
    (positions, indices)
}

fn le_bytes(values: impl Iterator<Item = f32>) -> Vec<u8> {
    values.flat_map(f32::to_le_bytes).collect()
}

/// A colour as linear RGB relative to white, scaled to a Rec. 709 luminance of 1: a
/// material's diffuse albedo (or a metal's F0) is its grey value times this.
pub use crate::image::colour::{Rgb, luminance};

/// A text that is not a colour.
#[derive(Debug, thiserror::Error)]
#[error("a colour is three numbers r,g,b ≥ 0, not all 0, not {0:?}")]
pub struct ColourError(String);

/// `r,g,b` (linear, any scale) as a colour of luminance 1: three finite numbers ≥ 0 of a
/// luminance above 0.
pub fn parse_colour(text: &str) -> Result<Rgb, ColourError> {
    let bad = || ColourError(text.to_string());
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>().map_err(|_| bad()))
        .collect::<Result<_, _>>()?;
    let [r, g, b] = values[..] else {
        return Err(bad());
    };
    let rgb = [r, g, b];
    let y = luminance(rgb);
    if rgb.iter().any(|v| !v.is_finite() || *v < 0.0) || !(y > 0.0 && y.is_finite()) {
        return Err(bad());
    }
    Ok(rgb.map(|v| v / y))
}

/// The material's JSON: metallic-roughness, and the extensions it needs; `colour` tints
/// the base colour (a dielectric's diffuse, a metal's F0), kept within 1 by its hue.
fn material_json(name: &str, pbr: &Pbr, colour: Option<Rgb>) -> (Value, Vec<&'static str>) {
    // A channel beyond 1 scales the three down together: the hue is kept, the albedo
    // cannot exceed 1.
    let tinted = colour
        .unwrap_or([1.0; 3])
        .map(|k| (pbr.base_color * k).max(0.0));
    let peak = tinted.iter().copied().fold(1.0, f64::max);
    let [r, g, b] = tinted.map(|v| v / peak);
    let mut material = json!({
        "name": name,
        "pbrMetallicRoughness": {
            "baseColorFactor": [r, g, b, 1.0],
            "metallicFactor": pbr.metallic,
            "roughnessFactor": pbr.roughness,
        },
    });
    let mut used = Vec::new();
    let mut extensions = serde_json::Map::new();
    if pbr.metallic < 1.0 && pbr.ior != DEFAULT_IOR {
        extensions.insert("KHR_materials_ior".into(), json!({"ior": pbr.ior}));
        used.push("KHR_materials_ior");
    }
    if pbr.metallic < 1.0 && pbr.specular < 1.0 {
        extensions.insert(
            "KHR_materials_specular".into(),
            json!({"specularFactor": pbr.specular}),
        );
        used.push("KHR_materials_specular");
    }
    if !extensions.is_empty() {
        material["extensions"] = Value::Object(extensions);
    }
    (material, used)
}

/// How an asset is written: JSON with its buffer as a base64 data URI (`.gltf`), or the
/// binary container (`.glb`: a JSON chunk and a binary chunk).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Container {
    /// JSON with the buffer as a base64 data URI.
    Gltf,
    /// The binary container.
    Glb,
}

impl Container {
    /// `.glb` for a path ending so (any case), else `.gltf`.
    pub fn of_path(path: &std::path::Path) -> Container {
        match path.extension() {
            Some(e) if e.eq_ignore_ascii_case("glb") => Container::Glb,
            _ => Container::Gltf,
        }
    }

    /// The media type to serve it as (`model/gltf+json`, `model/gltf-binary`).
    pub fn media_type(self) -> &'static str {
        match self {
            Container::Gltf => "model/gltf+json",
            Container::Glb => "model/gltf-binary",
        }
    }

    /// The file extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            Container::Gltf => "gltf",
            Container::Glb => "glb",
        }
    }
}

/// A unit sphere with a material, ready to be written in either container.
#[derive(Clone, Debug)]
pub struct SphereAsset {
    /// The document, its one buffer without a `uri`.
    json: Value,
    /// The buffer: positions, normals, indices (a multiple of 4 bytes).
    buffer: Vec<u8>,
}

/// A sphere with `material`'s glTF material (tinted by `colour` when known), recording the
/// Ward parameters and the colour in `extras` with `about`.
pub fn sphere(material: &Material, colour: Option<Rgb>, about: Value) -> SphereAsset {
    let name = material.name.as_str();
    let pbr = pbr_of(&material.ward);
    let (positions, indices) = sphere_mesh(32, 64);
    // On a unit sphere the normal is the position.
    let mut buffer = le_bytes(positions.iter().flatten().copied());
    let normals_at = buffer.len();
    buffer.extend(le_bytes(positions.iter().flatten().copied()));
    let indices_at = buffer.len();
    buffer.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    let vertex_bytes = normals_at;
    let index_bytes = buffer.len() - indices_at;
    while buffer.len() % 4 != 0 {
        buffer.push(0);
    }
    let (material_json, used) = material_json(name, &pbr, colour);
    let mut json = json!({
        "asset": {"version": "2.0", "generator": concat!("reflectance ", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": name}],
        "meshes": [{"name": name, "primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 1},
            "indices": 2,
            "material": 0,
        }]}],
        "materials": [material_json],
        "buffers": [{"byteLength": buffer.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": vertex_bytes, "target": 34962},
            {"buffer": 0, "byteOffset": normals_at, "byteLength": vertex_bytes, "target": 34962},
            {"buffer": 0, "byteOffset": indices_at, "byteLength": index_bytes, "target": 34963},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": positions.len(), "type": "VEC3",
             "min": [-1.0, -1.0, -1.0], "max": [1.0, 1.0, 1.0]},
            {"bufferView": 1, "componentType": 5126, "count": positions.len(), "type": "VEC3"},
            {"bufferView": 2, "componentType": 5123, "count": indices.len(), "type": "SCALAR"},
        ],
        "extras": {
            "ward": material.ward,
            "colour": colour,
            "about": about,
        },
    });
    if !used.is_empty() {
        json["extensionsUsed"] = json!(used);
    }
    SphereAsset { json, buffer }
}

impl SphereAsset {
    /// The document as `.gltf` holds it (the buffer a data URI).
    pub fn gltf_json(&self) -> Value {
        use base64::Engine;
        let mut json = self.json.clone();
        json["buffers"][0]["uri"] = Value::String(format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&self.buffer)
        ));
        json
    }

    /// The file's bytes in `container`.
    pub fn encode(&self, container: Container) -> Vec<u8> {
        match container {
            Container::Gltf => serde_json::to_vec(&self.gltf_json()).unwrap_or_default(),
            Container::Glb => self.glb(),
        }
    }

    /// glTF's binary container: a 12-byte header, the JSON chunk (padded with spaces),
    /// the binary chunk (padded with zeros), every length little-endian.
    fn glb(&self) -> Vec<u8> {
        let mut json = serde_json::to_vec(&self.json).unwrap_or_default();
        while !json.len().is_multiple_of(4) {
            json.push(b' ');
        }
        let total = 12 + 8 + json.len() + 8 + self.buffer.len();
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&json);
        out.extend_from_slice(&(self.buffer.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&self.buffer);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ward(rho_d: f64, rho_s: f64, alpha: f64) -> Ward {
        Ward {
            rho_d,
            rho_s,
            alpha,
        }
    }

    /// The mapping of these parameters.
    fn pbr(rho_d: f64, rho_s: f64, alpha: f64) -> Pbr {
        pbr_of(&ward(rho_d, rho_s, alpha))
    }

    /// The disc mean of Schlick's weight, by quadrature.
    #[test]
    fn the_disc_mean_of_the_fresnel_weight_is_one_twenty_first() {
        let n = 100_000;
        let mean: f64 = (0..n)
            .map(|i| {
                let u = (i as f64 + 0.5) / n as f64;
                (1.0 - (1.0 - u).sqrt()).powi(5)
            })
            .sum::<f64>()
            / n as f64;
        assert!((mean - DISC_FRESNEL_WEIGHT).abs() < 1e-6, "{mean}");
    }

    /// Known answers of the exact Fresnel term: normal incidence, grazing, glass at 45°.
    #[test]
    fn the_fresnel_term_is_the_exact_one() {
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-12);
        assert_eq!(fresnel_dielectric(0.0, 1.5), 1.0);
        // Rs 0.092013, Rp 0.008468 for n 1.5 at 45°.
        let c = std::f64::consts::FRAC_1_SQRT_2;
        assert!((fresnel_dielectric(c, 1.5) - 0.050_240_5).abs() < 1e-6);
        assert_eq!(fresnel_dielectric(0.3, 1.0), 0.0);
        for f0 in [0.0, 0.01, 0.04, 0.25, 0.9] {
            assert!((fresnel_dielectric(1.0, ior_of_f0(f0)) - f0).abs() < 1e-12);
        }
    }

    /// Every index written is ≥ 1 (below 1 Blender draws a mirror), and the F0 it gives
    /// balances the centre's loss against the rim's rise: the specular part's brightness
    /// over the disc, under real light, is ρs.
    #[test]
    fn dielectrics_keep_their_brightness_with_a_real_index() {
        for (rho_d, rho_s, alpha) in [
            (0.05, 0.05, 0.0),
            (0.25, 0.05, 0.01),
            (0.1, 0.1, 0.01),
            (0.25, 0.1, 0.0),
            (0.7, 0.2, 0.0),
            (0.7, 0.25, 0.02),
        ] {
            let p = pbr(rho_d, rho_s, alpha);
            assert_eq!((p.metallic, p.specular), (0.0, 1.0), "{p:?}");
            assert!(p.ior >= 1.0, "{p:?}");
            let f0 = fresnel_dielectric(1.0, p.ior);
            assert!(
                f0 < rho_s,
                "the rim's rise is paid for at the centre: {p:?}"
            );
            let w = GRAZING_LIGHT;
            let brightness = (1.0 - w) * f0 + w * disc_fresnel(f0);
            assert!((brightness - rho_s).abs() < 1e-9, "{rho_s}: {brightness}");
            assert!((p.base_color * (1.0 - f0) - rho_d).abs() < 1e-9, "{p:?}");
            assert!((p.roughness * p.roughness - GGX_ALPHA_SCALE * alpha).abs() < 1e-12);
        }
        // A dielectric as shiny as a metal: the exact term's dip at Brewster's angle lifts F0
        // above ρs; the index stays a real one.
        let glaze = pbr(0.1, 0.9, 0.1);
        let f0 = fresnel_dielectric(1.0, glaze.ior);
        assert!(glaze.ior > 1.0 && f0 < 0.99, "{glaze:?}");
        let w = GRAZING_LIGHT;
        assert!(((1.0 - w) * f0 + w * disc_fresnel(f0) - 0.9).abs() < 1e-9);
        // Classes of the paper's Fig. 11, against the rule solved independently (numpy, 20 000
        // points of the disc): F0 0.0316 and 0.2403.
        let gray_shiny = pbr(0.25, 0.05, 0.01);
        assert!((gray_shiny.ior - 1.4326).abs() < 2e-3, "{gray_shiny:?}");
        let white_shiny = pbr(0.7, 0.25, 0.01);
        assert!((white_shiny.ior - 2.9232).abs() < 5e-3, "{white_shiny:?}");
    }

    /// Matte surfaces reflect nothing; metals average ρs over the disc.
    #[test]
    fn mattes_and_metals() {
        let matte = pbr(0.9, 0.0, 0.0);
        assert_eq!(
            (matte.base_color, matte.specular, matte.metallic),
            (0.9, 0.0, 0.0)
        );
        for rho_s in [0.75, 0.3, 0.05] {
            let metal = pbr(0.0, rho_s, 0.0);
            assert_eq!(metal.metallic, 1.0);
            let mean = metal.base_color + (1.0 - metal.base_color) * DISC_FRESNEL_WEIGHT;
            assert!((mean - rho_s).abs() < 1e-9, "{rho_s}: {metal:?}");
        }
        assert_eq!(pbr(0.05, 0.05, 0.0).metallic, 0.0);
    }

    #[test]
    fn the_asset_holds_a_closed_sphere_and_only_the_extensions_it_uses() {
        let material =
            |name: &str, rho_d, rho_s, alpha| Material::new(name, ward(rho_d, rho_s, alpha));
        let chrome = sphere(&material("chrome", 0.0, 0.75, 0.0), None, Value::Null).gltf_json();
        assert!(chrome.get("extensionsUsed").is_none());
        let dull = sphere(&material("black", 0.05, 0.02, 0.1), None, Value::Null).gltf_json();
        let ior = &dull["materials"][0]["extensions"]["KHR_materials_ior"]["ior"];
        assert!(ior.as_f64().is_some_and(|ior| ior > 1.0), "{ior}");
        assert_eq!(dull["extensionsUsed"], json!(["KHR_materials_ior"]));
        let matte = sphere(&material("white", 0.9, 0.0, 0.0), None, Value::Null).gltf_json();
        assert_eq!(matte["extensionsUsed"], json!(["KHR_materials_specular"]));
        let (positions, indices) = sphere_mesh(32, 64);
        assert!(indices.iter().all(|&i| (i as usize) < positions.len()));
        assert_eq!(dull["accessors"][2]["count"], indices.len());
        assert_eq!(dull["extras"]["ward"]["rho_s"], 0.02);
    }

    /// The binary container as its specification lays it out, holding the same document
    /// and buffer as the `.gltf`.
    #[test]
    fn glb_is_the_binary_container_of_the_same_asset() {
        use base64::Engine;
        let asset = sphere(
            &Material::new("gray_shiny", ward(0.25, 0.05, 0.01)),
            None,
            json!({"source": "test"}),
        );
        let glb = asset.encode(Container::Glb);
        let word = |at: usize| u32::from_le_bytes(glb[at..at + 4].try_into().unwrap()) as usize;
        assert_eq!(&glb[0..4], b"glTF");
        assert_eq!(word(4), 2);
        assert_eq!(word(8), glb.len());
        let json_length = word(12);
        assert_eq!(&glb[16..20], b"JSON");
        assert_eq!(json_length % 4, 0);
        let doc: Value = serde_json::from_slice(&glb[20..20 + json_length]).unwrap();
        let bin_at = 20 + json_length;
        assert_eq!(&glb[bin_at + 4..bin_at + 8], b"BIN\0");
        let bin = &glb[bin_at + 8..];
        assert_eq!(word(bin_at), bin.len());
        assert!(doc["buffers"][0].get("uri").is_none());
        assert_eq!(doc["buffers"][0]["byteLength"], bin.len());
        let gltf = asset.gltf_json();
        let uri = gltf["buffers"][0]["uri"].as_str().unwrap();
        let embedded = base64::engine::general_purpose::STANDARD
            .decode(uri.split_once(',').unwrap().1)
            .unwrap();
        assert_eq!(embedded, bin);
        assert_eq!(doc["materials"], gltf["materials"]);
        assert_eq!(
            Container::of_path(std::path::Path::new("a/B.GLB")),
            Container::Glb
        );
        assert_eq!(
            Container::of_path(std::path::Path::new("a.gltf")),
            Container::Gltf
        );
    }

    /// A colour tints the base colour and is recorded; luminance-1 colours keep the grey
    /// value as their luminance.
    #[test]
    fn colour_tints_the_base_colour() {
        let red: Rgb = [2.5, 0.6, 0.5];
        let y = luminance(red);
        let red = red.map(|k| k / y);
        assert!((luminance(red) - 1.0).abs() < 1e-12);
        let plastic = Material::new("red", ward(0.3, 0.05, 0.02));
        let doc = sphere(&plastic, Some(red), Value::Null).gltf_json();
        let base: Vec<f64> = doc["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let grey = pbr(0.3, 0.05, 0.02).base_color;
        assert!(
            (luminance([base[0], base[1], base[2]]) - grey).abs() < 1e-9,
            "{base:?}"
        );
        assert!(base[0] > base[1] && base[1] > base[2] * 0.9, "{base:?}");
        assert_eq!(doc["extras"]["colour"][0], red[0]);
        let grey_doc = sphere(&plastic, None, Value::Null).gltf_json();
        assert!(grey_doc["extras"]["colour"].is_null());
    }
}
