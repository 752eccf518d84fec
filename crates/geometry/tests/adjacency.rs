//! Adjacency and topology on every fixture: each mesh edge listed once, symmetric neighbour
//! lists, vertex–face lists that match the triangles, and the Euler characteristic
//! (2 for the genus-0 bodies, 0 for the torus) reported by validation.

use std::collections::{BTreeMap, BTreeSet};

use crate::common::*;

#[test]
fn adjacency_matches_the_triangles() {
    for &(name, genus) in FIXTURES {
        let file = load(name);
        let m = &file.mesh;
        let n = m.n_vertices();
        let adj = m.adjacency();

        // Edges counted here from the triangles: each closed-surface edge is used by two faces.
        let mut uses: BTreeMap<(u32, u32), usize> = BTreeMap::new();
        for t in m.triangles() {
            for e in 0..3 {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                *uses.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        assert!(uses.values().all(|&u| u == 2), "{name}: every edge of a closed surface has two faces");
        assert_eq!(uses.len() * 2, m.n_faces() * 3, "{name}: E = 3F/2");

        let edges = adj.edges();
        let listed: BTreeSet<(u32, u32)> = edges.iter().map(|e| (e[0], e[1])).collect();
        assert_eq!(listed.len(), edges.len(), "{name}: an edge is listed twice");
        assert!(edges.iter().all(|e| e[0] < e[1]), "{name}: edges are (low, high)");
        let expected: BTreeSet<(u32, u32)> = uses.keys().copied().collect();
        assert_eq!(listed, expected, "{name}: edge set");

        for v in 0..n {
            let nb = adj.neighbors_of(v);
            assert!(nb.windows(2).all(|w| w[0] < w[1]), "{name}: neighbours of {v} sorted and unique");
            assert!(!nb.contains(&(v as u32)), "{name}: {v} is not its own neighbour");
            for &w in nb {
                assert!(
                    adj.neighbors_of(w as usize).contains(&(v as u32)),
                    "{name}: {v} -> {w} not symmetric"
                );
                assert!(expected.contains(&((v as u32).min(w), (v as u32).max(w))), "{name}: ({v}, {w})");
            }
            let mut faces: Vec<u32> = adj.faces_of(v).to_vec();
            faces.sort_unstable();
            let want: Vec<u32> = (0..m.n_faces() as u32)
                .filter(|&k| m.triangles()[k as usize].contains(&(v as u32)))
                .collect();
            assert_eq!(faces, want, "{name}: faces of {v}");
            // A closed manifold vertex has as many faces as neighbours (one fan).
            assert_eq!(faces.len(), nb.len(), "{name}: vertex {v}");
        }

        // Euler characteristic from the counts made here; the genus is known per fixture
        // (summed over its closed surfaces: the outer one and any cavities).
        let chi = n as i64 - uses.len() as i64 + m.n_faces() as i64;
        let surfaces = m.shells().len() as i64;
        assert_eq!(chi, 2 * surfaces - 2 * genus, "{name}: V - E + F");
        assert_eq!(file.validation.euler_characteristic, chi, "{name}");
        assert_eq!(file.validation.genus, genus, "{name}");
    }
}
