//! A tool defined here, outside the library: a spring that pulls one vertex toward a point.
//! It is one type implementing [`Tool`]; a [`ToolSet`] drives it through a body with no
//! change to the library (no protocol, no parser, no enum of tools).

use fibfluid_geometry::Vec3;
use fibfluid_geometry::vec3::{dist, dot, scale, sub};
use fibfluid_interact::{Hold, Interactive, Result, Storage, Tool, ToolLoad, ToolSet};
use fibfluid_sim::ConstraintKind;

use super::tools::lowest;
use super::{body, sphere};

/// Pulls `vertex` toward `target` with a spring of stiffness `k` (N/m), from where the last
/// frame left it.
#[derive(Debug)]
struct Pull {
    vertex: usize,
    target: Vec3,
    k: f64,
}

impl Pull {
    fn force(&self, body: &dyn Interactive) -> Vec3 {
        scale(sub(self.target, body.positions()[self.vertex]), self.k)
    }
}

impl Tool for Pull {
    fn hold(&mut self, body: &mut dyn Interactive) -> Result<()> {
        let f = self.force(&*body);
        body.push(self.vertex, f)
    }

    fn release(&mut self, body: &mut dyn Interactive) -> Result<()> {
        body.release(self.vertex)
    }

    fn load(&self, body: &dyn Interactive, _to_file: &[u32]) -> ToolLoad {
        let force = body.reactions().iter().find(|r| r.0 == self.vertex).map_or([0.0; 3], |r| r.1);
        ToolLoad::Other { tool: "pull".into(), force }
    }
}

#[test]
fn a_tool_defined_outside_the_library_pulls_a_vertex_through_a_tool_set() {
    let scene = sphere(ConstraintKind::Eliminate);
    let mut b = body(&scene, Storage::F64);
    let mut pushed = b.clone();
    let v = lowest(&b);
    let start = b.positions()[v];
    let base = b.positions().to_vec();
    let target = [start[0] + 0.05, start[1] - 0.05, start[2]];
    let pull = Pull { vertex: v, target, k: 0.5 };
    let f = pull.force(&b);
    let to_file: Vec<u32> = (0..b.n_vertices() as u32).collect();
    let mut tools = ToolSet::default();
    let id = tools.add(Box::new(pull)).unwrap();

    let loads = tools.frame(&mut b, &to_file).unwrap();
    assert_eq!(loads, vec![ToolLoad::Other { tool: "pull".into(), force: f }]);
    assert_eq!(b.holds().to_vec(), vec![(v, Hold::Push { force: f })]);
    let moved = sub(b.positions()[v], start);
    assert!(dot(moved, sub(target, start)) > 0.0, "the vertex moves toward the target: {moved:?}");
    assert!(dist(b.positions()[v], target) < dist(start, target));
    // The frame is the body's own answer to that push.
    pushed.push(v, f).unwrap();
    pushed.update().unwrap();
    assert_eq!(b.positions(), pushed.positions());

    // A second frame pulls from where the first left the vertex.
    let second = Pull { vertex: v, target, k: 0.5 }.force(&b);
    let loads = tools.frame(&mut b, &to_file).unwrap();
    assert_eq!(loads, vec![ToolLoad::Other { tool: "pull".into(), force: second }]);

    // Removed, the tool's hold goes and the body returns to its base state.
    assert!(tools.remove(&mut b, id).unwrap());
    assert!(!tools.remove(&mut b, id).unwrap());
    assert!(tools.frame(&mut b, &to_file).unwrap().is_empty());
    assert!(b.holds().is_empty());
    let back = b.positions().iter().zip(&base).map(|(p, q)| dist(*p, *q)).fold(0.0, f64::max);
    assert!(back < 1e-12, "back at the base state to {back:e}");
}
