//! The plan of a glTF write-back: which original vertex blocks the primitives share, the final
//! UV of every vertex, and the vertices that must be duplicated because their corners now
//! disagree on the UV.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use serde_json::{Map, Value};

use super::super::accessor::{Accessor, opt_usize};
use super::super::reader::for_each_triangle;
use super::super::source::BufferData;
use super::super::{GltfScene, PrimitiveSpan};
use crate::index::MaterialId;
use crate::io::IoError;
use crate::model::{Face, Model};

/// A block of glTF vertices shared by the primitives that use the same attribute accessors.
pub(super) struct BlockPlan {
    pub(super) base: u32,
    pub(super) count: u32,
    pub(super) spans: Vec<usize>,
    /// Final UV per output vertex (original vertices, then the duplicates), OBJ convention.
    pub(super) uvs: Vec<[f64; 2]>,
    pub(super) any_uv: bool,
    /// Original vertex each duplicate copies.
    pub(super) extras: Vec<u32>,
    pub(super) attrs: Map<String, Value>,
    pub(super) targets: Option<Value>,
}

/// The plan for one primitive span.
pub(super) struct SpanPlan {
    /// Output vertex of every corner, in face order.
    pub(super) corners: Vec<u32>,
    pub(super) remapped: bool,
    /// `Some(m)` when every face has material `m`; `None` when mixed or empty.
    pub(super) uniform: Option<Option<MaterialId>>,
}

/// What the write-back will do: the vertex blocks with their final UVs and duplicates, and per
/// primitive span the output vertex of every corner.
pub(super) struct Plan {
    pub(super) blocks: Vec<BlockPlan>,
    pub(super) spans: Vec<SpanPlan>,
    pub(super) span_block: Vec<usize>,
}

/// Checks that the faces still map onto the original primitives (`None` otherwise) and plans
/// the UV of every vertex, duplicating vertices whose corners now disagree.
pub(super) fn plan(
    model: &Model,
    scene: &GltfScene,
    sources: &[BufferData],
    path: &Path,
) -> Result<Option<Plan>, IoError> {
    let Some(Grouping { mut blocks, span_block }) = group_blocks(model, scene, sources)? else {
        return Ok(None);
    };
    let mut spans: Vec<SpanPlan> = Vec::with_capacity(scene.primitives.len());
    for _ in &scene.primitives {
        spans.push(SpanPlan { corners: Vec::new(), remapped: false, uniform: None });
    }
    for block in &mut blocks {
        assign_block_uvs(model, scene, block, &mut spans, path)?;
    }
    Ok(Some(Plan { blocks, spans, span_block }))
}

/// The vertex blocks and the block of every primitive span.
struct Grouping {
    blocks: Vec<BlockPlan>,
    span_block: Vec<usize>,
}

/// Groups the primitive spans into vertex blocks and checks that positions and corners still
/// match the document; `None` on a mismatch.
fn group_blocks(
    model: &Model,
    scene: &GltfScene,
    sources: &[BufferData],
) -> Result<Option<Grouping>, IoError> {
    let orig = &scene.document;
    let prim_json = |s: &PrimitiveSpan| -> Option<&Value> {
        orig.get("meshes")?.get(s.mesh as usize)?.get("primitives")?.get(s.primitive as usize)
    };
    let mut block_of_base: BTreeMap<u32, usize> = BTreeMap::new();
    let mut blocks: Vec<BlockPlan> = Vec::new();
    let mut span_block = Vec::with_capacity(scene.primitives.len());
    for (si, s) in scene.primitives.iter().enumerate() {
        let Some(prim) = prim_json(s) else { return Ok(None) };
        let Some(attrs) = prim.get("attributes").and_then(Value::as_object) else {
            return Ok(None);
        };
        let b = match block_of_base.get(&s.vertex_base) {
            Some(&b) => b,
            None => {
                let Some(block) = new_block(model, scene, sources, s, prim, attrs)? else {
                    return Ok(None);
                };
                blocks.push(block);
                block_of_base.insert(s.vertex_base, blocks.len() - 1);
                blocks.len() - 1
            }
        };
        blocks[b].spans.push(si);
        span_block.push(b);
        if !corners_match(model, scene, sources, s, prim)? {
            return Ok(None);
        }
    }
    Ok(Some(Grouping { blocks, span_block }))
}

/// The block that starts at span `s`'s vertices, or `None` when its positions no longer match
/// the model's.
fn new_block(
    model: &Model,
    scene: &GltfScene,
    sources: &[BufferData],
    s: &PrimitiveSpan,
    prim: &Value,
    attrs: &Map<String, Value>,
) -> Result<Option<BlockPlan>, IoError> {
    let Some(pi) = attrs.get("POSITION").and_then(Value::as_u64) else {
        return Ok(None);
    };
    let pos = Accessor::new(&scene.source, &scene.document, sources, pi as usize)?;
    if pos.count != s.vertex_count as usize {
        return Ok(None);
    }
    let base = s.vertex_base as usize;
    for i in 0..pos.count {
        let p = [pos.get(i, 0), pos.get(i, 1), pos.get(i, 2)];
        if model.positions[base + i] != p {
            return Ok(None);
        }
    }
    Ok(Some(BlockPlan {
        base: s.vertex_base,
        count: s.vertex_count,
        spans: Vec::new(),
        uvs: Vec::new(),
        any_uv: false,
        extras: Vec::new(),
        attrs: attrs.clone(),
        targets: prim.get("targets").cloned(),
    }))
}

/// Whether span `s`'s faces still have exactly the corners its primitive's triangles give.
fn corners_match(
    model: &Model,
    scene: &GltfScene,
    sources: &[BufferData],
    s: &PrimitiveSpan,
    prim: &Value,
) -> Result<bool, IoError> {
    let src = &scene.source;
    let ctx = format!("meshes[{}].primitives[{}]", s.mesh, s.primitive);
    let indices = match opt_usize(prim, "indices", &ctx).map_err(|m| IoError::invalid(src, m))? {
        Some(i) => Some(Accessor::new(src, &scene.document, sources, i)?),
        None => None,
    };
    let mut f = s.first_face as usize;
    let mut same = true;
    for_each_triangle(src, &ctx, s.mode, indices.as_ref(), s.vertex_count as usize, |t| {
        if same {
            let v = model.faces[f].v;
            same = (0..3).all(|k| v[k].0 == s.vertex_base + t[k]);
        }
        f += 1;
    })?;
    Ok(same && f == (s.first_face + s.face_count) as usize)
}

/// The UV of every vertex of one block and the output vertex of every corner of its spans,
/// duplicating a vertex for each further UV its corners ask for.
fn assign_block_uvs(
    model: &Model,
    scene: &GltfScene,
    block: &mut BlockPlan,
    spans: &mut [SpanPlan],
    path: &Path,
) -> Result<(), IoError> {
    let n = block.count as usize;
    let mut uvs = BlockUvs { assigned: vec![None; n], dup: HashMap::new(), extra_uvs: Vec::new() };
    // Indexed, because the loop body also grows the block's duplicates.
    for span in 0..block.spans.len() {
        let si = block.spans[span];
        let s = &scene.primitives[si];
        let plan = &mut spans[si];
        plan.corners.reserve(s.face_count as usize * 3);
        let faces = &model.faces[s.first_face as usize..(s.first_face + s.face_count) as usize];
        let mut mixed = false;
        for (j, face) in faces.iter().enumerate() {
            if j == 0 {
                plan.uniform = Some(face.material);
            } else if plan.uniform != Some(face.material) {
                mixed = true;
            }
            for k in 0..3 {
                let out = uvs.corner_vertex(model, face, k, block, plan);
                plan.corners.push(out);
            }
        }
        if mixed {
            plan.uniform = None;
        }
    }
    if n + block.extras.len() > u32::MAX as usize {
        return Err(IoError::unsupported(path, "splitting UV seams would exceed 2^32 vertices"));
    }
    block.uvs =
        uvs.assigned.into_iter().map(|a| a.unwrap_or([0.0, 0.0])).chain(uvs.extra_uvs).collect();
    Ok(())
}

/// The UVs handed out so far in one block.
struct BlockUvs {
    /// The UV of each original vertex, once a corner has claimed it.
    assigned: Vec<Option<[f64; 2]>>,
    /// The duplicate made for (original vertex, u bits, v bits).
    dup: HashMap<(u32, u64, u64), u32>,
    /// The UV of each duplicate, in the order they were made.
    extra_uvs: Vec<[f64; 2]>,
}

impl BlockUvs {
    /// The output vertex of corner `k` of `face`: its original vertex when that vertex has no UV
    /// yet or the same one, else the duplicate for this UV (made on first use).
    fn corner_vertex(
        &mut self,
        model: &Model,
        face: &Face,
        k: usize,
        block: &mut BlockPlan,
        plan: &mut SpanPlan,
    ) -> u32 {
        let gv = face.v[k].0 - block.base;
        let Some(t) = face.uv else { return gv };
        let uv = model.uvs[t[k].idx()];
        block.any_uv = true;
        match self.assigned[gv as usize] {
            None => {
                self.assigned[gv as usize] = Some(uv);
                gv
            }
            Some(a) if a[0].to_bits() == uv[0].to_bits() && a[1].to_bits() == uv[1].to_bits() => gv,
            Some(_) => {
                plan.remapped = true;
                let key = (gv, uv[0].to_bits(), uv[1].to_bits());
                let next = (block.count as usize + block.extras.len()) as u32;
                let id = *self.dup.entry(key).or_insert(next);
                if id == next {
                    block.extras.push(gv);
                    self.extra_uvs.push(uv);
                }
                id
            }
        }
    }
}
