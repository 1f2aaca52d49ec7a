//! Small 2-D geometry shared by the engine and the plugins: closed-form 2×2 SVD, the isometric
//! (ARAP) energy of a triangle against its target, rigid least-squares fits, robust predicates.
