//! A Ward material as glTF 2.0: the mapping onto glTF's metallic-roughness model (with
//! `KHR_materials_ior` and `KHR_materials_specular` where the plain model cannot hold the
//! Ward parameters), and a sphere asset carrying it, self-contained (one `.gltf` file).
//!
//! **The mapping** (its error, rendered under the light probes: docs/accuracy.md). glTF's
//! specular lobe is GGX with Schlick's Fresnel F = F0 + (F90 − F0)(1 − v·h)⁵; Ward's is a
//! Gaussian of slope with a constant weight ρs.
//!
//! * roughness: GGX's α = roughness². GGX and Ward's Gaussian agree at their peak for the
//!   same α, but GGX's tails hold more of the light, so the same α looks broader under a
//!   sun; `roughness = √(0.7 α)` ([`GGX_ALPHA_SCALE`], the scale of 0.4–1.3 that
//!   differed least from Ward's highlights under the probes) and 0 for the ideal mirror;
//! * a dielectric takes Ward's constant weight exactly: `KHR_materials_ior` with `ior` 0
//!   makes the Fresnel term's F0 factor 1 (the extension's own route for specular-glossiness
//!   materials), and `KHR_materials_specular`'s `specularFactor` = ρs then gives
//!   F0 = F90 = ρs at every angle; glTF weights the diffuse by 1 − F, so
//!   `baseColor = ρd / (1 − ρs)`. Without a specular part (ρs = 0), `specularFactor` 0;
//! * a material whose diffuse part is under a tenth of its specular one is a metal
//!   (`metallic` 1), which every glTF viewer draws without extensions: its Fresnel term
//!   rises to 1 at grazing angles, so `baseColor` is the F0 whose mean over a sphere's disc
//!   is ρs. Over the disc cos θ = √(1 − ρ²) with ρ² uniform, so the mean of (1 − cos θ)⁵ is
//!   1/21 and F0 = (ρs − 1/21) / (1 − 1/21); ρd is dropped.

use serde_json::{Value, json};

/// Over a sphere's disc, the mean of Schlick's (1 − cos θ)⁵.
pub const DISC_FRESNEL_WEIGHT: f64 = 1.0 / 21.0;
/// Below this ratio ρd / ρs the material is exported as a metal.
pub const METAL_RATIO: f64 = 0.1;
/// GGX's α over Ward's: what differs least under the light probes (docs/accuracy.md).
pub const GGX_ALPHA_SCALE: f64 = 0.7;
/// glTF's index of refraction when `KHR_materials_ior` is absent.
pub const DEFAULT_IOR: f64 = 1.5;

/// The glTF metallic-roughness parameters of a Ward material (grey: one value per colour
/// channel).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pbr {
    pub base_color: f64,
    pub metallic: f64,
    pub roughness: f64,
    /// `KHR_materials_ior` (1.5 is glTF's default, and the extension is then left out; 0
    /// makes the Fresnel term's F0 factor 1).
    pub ior: f64,
    /// `KHR_materials_specular`'s `specularFactor` (1: left out).
    pub specular: f64,
}

/// The metal F0 whose mean over a sphere's disc is `rho_s`.
fn metal_f0(rho_s: f64) -> f64 {
    let w = DISC_FRESNEL_WEIGHT;
    ((rho_s - w) / (1.0 - w)).clamp(0.0, 1.0)
}

/// The mapping of (ρd, ρs, α) onto glTF's model (see the module's documentation).
pub fn pbr_of(rho_d: f64, rho_s: f64, alpha: f64) -> Pbr {
    let (rho_d, rho_s) = (rho_d.clamp(0.0, 1.0), rho_s.clamp(0.0, 1.0));
    let roughness = (GGX_ALPHA_SCALE * alpha.clamp(0.0, 1.0)).sqrt();
    if rho_s > 0.0 && rho_d < METAL_RATIO * rho_s {
        return Pbr {
            base_color: metal_f0(rho_s),
            metallic: 1.0,
            roughness,
            ior: DEFAULT_IOR,
            specular: 1.0,
        };
    }
    Pbr {
        base_color: (rho_d / (1.0 - rho_s).max(1e-6)).min(1.0),
        metallic: 0.0,
        roughness,
        ior: if rho_s > 0.0 { 0.0 } else { DEFAULT_IOR },
        specular: rho_s,
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

/// The material's JSON: metallic-roughness, and the extensions it needs.
fn material_json(name: &str, pbr: &Pbr) -> (Value, Vec<&'static str>) {
    let c = pbr.base_color;
    let mut material = json!({
        "name": name,
        "pbrMetallicRoughness": {
            "baseColorFactor": [c, c, c, 1.0],
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

/// A glTF 2.0 asset (JSON, its buffer embedded as a data URI): a unit sphere with the
/// material of (ρd, ρs, α), which it also records in `extras` with `about`.
pub fn sphere_asset(name: &str, rho_d: f64, rho_s: f64, alpha: f64, about: Value) -> Value {
    use base64::Engine;
    let pbr = pbr_of(rho_d, rho_s, alpha);
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
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(&buffer)
    );
    let (material, used) = material_json(name, &pbr);
    let mut asset = json!({
        "asset": {"version": "2.0", "generator": concat!("reflectance ", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": name}],
        "meshes": [{"name": name, "primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 1},
            "indices": 2,
            "material": 0,
        }]}],
        "materials": [material],
        "buffers": [{"byteLength": buffer.len(), "uri": uri}],
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
        "extras": {"ward": {"rho_d": rho_d, "rho_s": rho_s, "alpha": alpha}, "about": about},
    });
    if !used.is_empty() {
        asset["extensionsUsed"] = json!(used);
    }
    asset
}

#[cfg(test)]
mod tests {
    use super::*;

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

    /// glTF's Fresnel term of the exported material at every angle: a dielectric's is ρs
    /// (Ward's constant weight), a metal's averages ρs over the disc.
    #[test]
    fn the_exported_fresnel_term_is_rho_s() {
        for (rho_d, rho_s, alpha) in [
            (0.0, 0.75, 0.0),
            (0.7, 0.25, 0.02),
            (0.05, 0.05, 0.0),
            (0.9, 0.0, 0.0),
            (0.3, 0.02, 0.1),
        ] {
            let p = pbr_of(rho_d, rho_s, alpha);
            assert!((p.roughness * p.roughness - GGX_ALPHA_SCALE * alpha).abs() < 1e-12);
            if p.metallic == 1.0 {
                let mean = p.base_color + (1.0 - p.base_color) * DISC_FRESNEL_WEIGHT;
                assert!((mean - rho_s).abs() < 1e-9, "{rho_d} {rho_s}: {p:?}");
                continue;
            }
            let f0_of_ior = if p.ior == 0.0 {
                1.0
            } else {
                ((p.ior - 1.0) / (p.ior + 1.0)).powi(2)
            };
            let (f0, f90) = (f0_of_ior * p.specular, p.specular);
            if rho_s > 0.0 {
                assert!(
                    (f0 - rho_s).abs() < 1e-12 && (f90 - rho_s).abs() < 1e-12,
                    "{p:?}"
                );
            } else {
                assert_eq!((f0, f90), (0.0, 0.0), "{p:?}");
            }
            assert!((p.base_color * (1.0 - rho_s) - rho_d).abs() < 1e-9);
        }
        assert_eq!(pbr_of(0.0, 0.75, 0.0).metallic, 1.0);
        assert_eq!(pbr_of(0.05, 0.05, 0.0).metallic, 0.0);
    }

    #[test]
    fn the_asset_holds_a_closed_sphere_and_only_the_extensions_it_uses() {
        let chrome = sphere_asset("chrome", 0.0, 0.75, 0.0, Value::Null);
        assert!(chrome.get("extensionsUsed").is_none());
        let dull = sphere_asset("black", 0.05, 0.02, 0.1, Value::Null);
        assert_eq!(
            dull["materials"][0]["extensions"]["KHR_materials_ior"]["ior"],
            0.0
        );
        assert_eq!(
            dull["extensionsUsed"],
            json!(["KHR_materials_ior", "KHR_materials_specular"])
        );
        let (positions, indices) = sphere_mesh(32, 64);
        assert!(indices.iter().all(|&i| (i as usize) < positions.len()));
        assert_eq!(dull["accessors"][2]["count"], indices.len());
        assert_eq!(dull["extras"]["ward"]["rho_s"], 0.02);
    }
}
