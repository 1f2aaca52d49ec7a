//! The buffers of the overlap separation, held by the engine and reused for every attempt.

use crate::geometry::Tri2;

/// The second face of a pair that the separation watches: a face around the moving vertex (its
/// index in `faces`) or one that stays put (its index in `static_tris`).
#[derive(Clone, Copy, Debug)]
pub(crate) enum Other {
    Fan(u32),
    Static(u32),
}

/// The offending pairs, and the faces and triangles the separation of one vertex watches.
#[derive(Default)]
pub(crate) struct SeparateScratch {
    /// The overlapping face pairs left by a solve, flattened (`[f0, s0, f1, s1, ...]`): filled by
    /// the verdict, thinned by the separation, read by the freezing.
    pub(in crate::defrag) offenders: Vec<u32>,
    /// The free vertices of the offending faces, the candidates to move.
    pub(super) verts: Vec<u32>,
    /// The faces around the moving vertex.
    pub(super) faces: Vec<u32>,
    /// The pairs to watch: a face of `faces` (by index) and the other face.
    pub(super) tests: Vec<(u32, Other)>,
    /// The triangles of `faces` at the trial position, and of the faces that stay put.
    pub(super) fan_tris: Vec<Tri2>,
    pub(super) static_tris: Vec<Tri2>,
    /// The box each face of `faces` can sweep while its vertex moves.
    pub(super) swept: Vec<[f64; 4]>,
}
