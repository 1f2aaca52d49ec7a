//! The one union-find of the crate: disjoint sets over `0..n` with path halving, whose union keeps
//! the smaller root, so that a set's root is its smallest member whatever the order of unions.
//! [`UnionFind`] owns its parents; [`find`] and [`union`] work on a caller's reused `u32` buffer.

/// The root of `x` in the forest `parent`, halving the path on the way.
#[inline]
pub fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        let p = parent[parent[x as usize] as usize];
        parent[x as usize] = p;
        x = p;
    }
    x
}

/// Joins the sets of `a` and `b` in the forest `parent`, keeping the smaller root.
#[inline]
pub fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
        parent[hi as usize] = lo;
    }
}

/// Union-find over `u32` nodes. The larger root is always hooked under the smaller one, so each
/// component's root is its smallest node (as in evaluate.py) and `parent[x] <= x` holds, which
/// lets [`UnionFind::flatten`] resolve every node in one forward pass.
#[derive(Clone)]
pub struct UnionFind {
    parent: Vec<u32>,
}

impl UnionFind {
    /// `n` singleton sets.
    pub fn new(n: usize) -> Self {
        Self { parent: (0..n as u32).collect() }
    }

    /// The root of `x`, halving the path on the way.
    #[inline]
    pub fn find(&mut self, mut x: usize) -> usize {
        loop {
            let p = self.parent[x] as usize;
            if p == x {
                return x;
            }
            let gp = self.parent[p];
            self.parent[x] = gp;
            x = gp as usize;
        }
    }

    /// Joins the sets of `a` and `b`, keeping the smaller root.
    #[inline]
    pub fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
            self.parent[hi] = lo as u32;
        }
    }

    /// The number of components.
    pub fn count_roots(&self) -> u64 {
        self.parent.iter().enumerate().filter(|&(i, &p)| p as usize == i).count() as u64
    }

    /// The root (smallest node) of every node's component.
    pub fn flatten(&mut self) -> Vec<u32> {
        for x in 0..self.parent.len() {
            // parent[x] < x for non-roots and is already resolved, so one lookup suffices.
            let p = self.parent[x] as usize;
            self.parent[x] = self.parent[p];
        }
        self.parent.clone()
    }
}
