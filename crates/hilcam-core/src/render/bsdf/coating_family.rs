//! The coating tables of one dielectric index at every roughness a texture may give: a
//! rough plastic whose roughness varies over its surface (glTF's `metallicRoughnessTexture`,
//! MTL `map_Pr`) cannot tabulate its coating per hit ([`CoatingAlbedo::coupled`] takes
//! ~131 k samples), so the tables are made once at roughness nodes and a hit's is the
//! linear blend of its two neighbours'. Only the diffuse term's coupling is interpolated;
//! the specular term uses the hit's own α exactly.

use super::coating::{CoatingAlbedo, Coupling};
use super::ggx::{GgxDistribution, MIN_ALPHA};

/// Roughness nodes, `r = j/(NODES − 1)` (node 0 at the smoothest GGX, α = 1e-4). `E(μ)`
/// is smooth in roughness: with 33 nodes the blend's transmitted share is within 1e-3 of
/// the hit's own table away from grazing (within 5e-3 at grazing, where the cosine
/// weight is small; the unit test measures 8e-4 and 3.5e-3).
const NODES: usize = 33;

/// [`CoatingAlbedo`] at every roughness node for one index `eta` (energy coupling).
#[derive(Clone, Debug, PartialEq)]
pub struct CoatingFamily {
    pub eta: f32,
    tables: Vec<CoatingAlbedo>,
}

fn node_alpha(j: usize) -> f32 {
    let r = j as f32 / (NODES - 1) as f32;
    (r * r).max(MIN_ALPHA)
}

impl CoatingFamily {
    /// Bytes one family holds.
    pub const BYTES: usize = NODES * std::mem::size_of::<CoatingAlbedo>();

    /// Tabulate every node (a few hundred milliseconds; once per index in a scene).
    pub fn new(eta: f32) -> Self {
        let tables = (0..NODES)
            .map(|j| CoatingAlbedo::coupled(GgxDistribution { alpha: node_alpha(j) }, eta, Coupling::Energy))
            .collect();
        CoatingFamily { eta, tables }
    }

    /// The coating at `roughness` (α = roughness²), blended from its two nodes.
    #[inline]
    pub fn at(&self, roughness: f32) -> CoatingAlbedo {
        let t = roughness.clamp(0.0, 1.0) * (NODES - 1) as f32;
        let j = (t as usize).min(NODES - 2);
        CoatingAlbedo::blend(&self.tables[j], &self.tables[j + 1], t - j as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_node_is_its_own_table_and_between_nodes_the_blend_is_close_to_the_hit_s_own() {
        let family = CoatingFamily::new(1.5);
        let node = 0.5f32; // node 16
        let own = CoatingAlbedo::coupled(GgxDistribution { alpha: node * node }, 1.5, Coupling::Energy);
        assert_eq!(family.at(node), own);
        // Off the nodes: the transmitted share t(μ) within 1e-3 where the light is not
        // grazing (μ ≥ 0.1; the tables' own quadrature error is ~1e-4), within 5e-3 at
        // any μ (the smoothest coatings change fastest near grazing), and the diffuse
        // term's normalisation within 1e-3.
        let (mut worst, mut worst_grazing) = (0.0f32, 0.0f32);
        for r in [0.05f32, 0.13, 0.3, 0.51, 0.77, 0.99] {
            let own = CoatingAlbedo::coupled(GgxDistribution { alpha: r * r }, 1.5, Coupling::Energy);
            let got = family.at(r);
            for k in 0..=20 {
                let mu = k as f32 / 20.0;
                let d = (got.transmitted(mu) - own.transmitted(mu)).abs();
                if mu >= 0.1 {
                    worst = worst.max(d);
                } else {
                    worst_grazing = worst_grazing.max(d);
                }
            }
            assert!((got.norm / own.norm - 1.0).abs() < 1e-3, "r {r}: norm {} vs {}", got.norm, own.norm);
        }
        eprintln!("largest difference from the hit's own table: {worst:e} (μ ≥ 0.1), {worst_grazing:e} (μ < 0.1)");
        assert!(worst < 1e-3 && worst_grazing < 5e-3, "{worst} {worst_grazing}");
    }
}
