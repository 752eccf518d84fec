//! Compressed vertex adjacency (no fixed maximum valence, unlike the paper's `SharedMax`).

/// Vertex→face and vertex→vertex adjacency in compressed-row form.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Adjacency {
    face_start: Vec<u32>,
    faces: Vec<u32>,
    nbr_start: Vec<u32>,
    nbrs: Vec<u32>,
}

impl Adjacency {
    /// Builds the adjacency of `n` vertices from triangles.
    pub fn new(n: usize, triangles: &[[u32; 3]]) -> Self {
        let mut count = vec![0u32; n + 1];
        for t in triangles {
            for &v in t {
                count[v as usize + 1] += 1;
            }
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let mut faces = vec![0u32; count[n] as usize];
        let mut fill = count.clone();
        for (k, t) in triangles.iter().enumerate() {
            for &v in t {
                faces[fill[v as usize] as usize] = k as u32;
                fill[v as usize] += 1;
            }
        }
        let mut nbr_start = vec![0u32; n + 1];
        let mut nbrs = Vec::with_capacity(faces.len());
        for v in 0..n {
            let start = nbrs.len();
            for &k in &faces[count[v] as usize..count[v + 1] as usize] {
                for &w in &triangles[k as usize] {
                    if w as usize != v {
                        nbrs.push(w);
                    }
                }
            }
            nbrs[start..].sort_unstable();
            let mut dedup: Vec<u32> = nbrs[start..].to_vec();
            dedup.dedup();
            nbrs.truncate(start);
            nbrs.extend(dedup);
            nbr_start[v + 1] = nbrs.len() as u32;
        }
        Self { face_start: count, faces, nbr_start, nbrs }
    }

    /// Faces touching vertex `v`.
    pub fn faces_of(&self, v: usize) -> &[u32] {
        &self.faces[self.face_start[v] as usize..self.face_start[v + 1] as usize]
    }

    /// Vertices sharing an edge with `v`, sorted.
    pub fn neighbors_of(&self, v: usize) -> &[u32] {
        &self.nbrs[self.nbr_start[v] as usize..self.nbr_start[v + 1] as usize]
    }

    /// Every mesh edge once, as (a, b) with a < b.
    pub fn edges(&self) -> Vec<[u32; 2]> {
        let n = self.nbr_start.len() - 1;
        let mut out = Vec::new();
        for a in 0..n {
            for &b in self.neighbors_of(a) {
                if (a as u32) < b {
                    out.push([a as u32, b]);
                }
            }
        }
        out
    }
}
