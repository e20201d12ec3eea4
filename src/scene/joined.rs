//! Vertices joined into sets (union–find with path halving): the connected pieces of a mesh,
//! by whatever joins them (shared triangles, shared positions).

/// Sets of the vertices `0..count`, each named by its smallest member.
pub struct Joined {
    parent: Vec<u32>,
}

impl Joined {
    /// Every vertex in a set of its own.
    pub fn new(count: usize) -> Joined {
        Joined {
            parent: (0..count as u32).collect(),
        }
    }

    /// The smallest vertex of `v`'s set.
    pub fn root(&mut self, mut v: u32) -> u32 {
        while self.parent[v as usize] != v {
            let up = self.parent[self.parent[v as usize] as usize];
            self.parent[v as usize] = up;
            v = up;
        }
        v
    }

    /// Joins the sets of `a` and `b`.
    pub fn join(&mut self, a: u32, b: u32) {
        let (a, b) = (self.root(a), self.root(b));
        self.parent[a.max(b) as usize] = a.min(b);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sets_are_named_by_their_smallest_vertex() {
        let mut sets = Joined::new(6);
        sets.join(4, 2);
        sets.join(5, 4);
        sets.join(1, 3);
        assert_eq!(
            (0..6).map(|v| sets.root(v)).collect::<Vec<_>>(),
            [0, 1, 2, 1, 2, 2]
        );
        sets.join(3, 5);
        assert_eq!(
            (0..6).map(|v| sets.root(v)).collect::<Vec<_>>(),
            [0, 1, 1, 1, 1, 1]
        );
    }
}
