//! What a fragment shader does that hidden-surface removal cares about — discard, depth
//! written by the shader, storage writes, early fragment tests — read from its SPIR-V under the
//! pipeline's specialization constants, as a driver sees it after folding them.
//!
//! The shipped shaders select per material class with a specialization constant
//! (`MATERIAL_CLASS`): `forward_early.frag` holds the alpha test's `discard`, but an opaque
//! pipeline never reaches it. So the facts come from the blocks reachable from the entry point
//! once branches on specialization constants are folded (`OpSpecConstantOp` comparisons and
//! logic, `OpBranchConditional` and `OpSwitch` on a known value); a branch on anything else
//! keeps both sides. Pure: no Vulkan calls, tested without a device.
//!
//! Limits, on the safe side for shaders glslc writes: 64-bit constants are read by their low
//! word, and a store through a pointer passed as a function parameter or copied with
//! `OpCopyObject` is not followed to its storage class.

use std::collections::{HashMap, HashSet};

use crate::error::VkError;
use crate::shader::spirv_words;

/// Facts of a fragment shader under one specialization.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FragmentFacts {
    /// `OpKill`, `OpTerminateInvocation` or `OpDemoteToHelperInvocation` is reachable.
    pub discard: bool,
    /// A store to the `FragDepth` built-in is reachable.
    pub depth_write: bool,
    /// A store, image write or atomic on storage buffers or images is reachable.
    pub storage_writes: bool,
    /// `OpExecutionMode EarlyFragmentTests`.
    pub early_fragment_tests: bool,
}

mod op {
    pub const EXECUTION_MODE: u16 = 16;
    pub const DECORATE: u16 = 71;
    pub const CONSTANT_TRUE: u16 = 41;
    pub const CONSTANT_FALSE: u16 = 42;
    pub const CONSTANT: u16 = 43;
    pub const SPEC_CONSTANT_TRUE: u16 = 48;
    pub const SPEC_CONSTANT_FALSE: u16 = 49;
    pub const SPEC_CONSTANT: u16 = 50;
    pub const SPEC_CONSTANT_OP: u16 = 52;
    pub const FUNCTION: u16 = 54;
    pub const FUNCTION_CALL: u16 = 57;
    pub const VARIABLE: u16 = 59;
    pub const STORE: u16 = 62;
    pub const ACCESS_CHAIN: u16 = 65;
    pub const IN_BOUNDS_ACCESS_CHAIN: u16 = 66;
    pub const PTR_ACCESS_CHAIN: u16 = 67;
    pub const IMAGE_WRITE: u16 = 99;
    pub const LOGICAL_EQUAL: u16 = 164;
    pub const LOGICAL_NOT_EQUAL: u16 = 165;
    pub const LOGICAL_OR: u16 = 166;
    pub const LOGICAL_AND: u16 = 167;
    pub const LOGICAL_NOT: u16 = 168;
    pub const I_EQUAL: u16 = 170;
    pub const I_NOT_EQUAL: u16 = 171;
    pub const U_GREATER_THAN: u16 = 172;
    pub const U_GREATER_THAN_EQUAL: u16 = 174;
    pub const U_LESS_THAN: u16 = 176;
    pub const U_LESS_THAN_EQUAL: u16 = 178;
    pub const ATOMIC_LOAD: u16 = 227;
    pub const ATOMIC_STORE: u16 = 228;
    pub const ATOMIC_XOR: u16 = 242;
    pub const ATOMIC_FLAG_TEST_AND_SET: u16 = 318;
    pub const ATOMIC_FLAG_CLEAR: u16 = 319;
    pub const ATOMIC_F_ADD: u16 = 6035;
    pub const LABEL: u16 = 248;
    pub const BRANCH: u16 = 249;
    pub const BRANCH_CONDITIONAL: u16 = 250;
    pub const SWITCH: u16 = 251;
    pub const KILL: u16 = 252;
    pub const TERMINATE_INVOCATION: u16 = 4416;
    pub const DEMOTE_TO_HELPER_INVOCATION: u16 = 5380;
    pub const ENTRY_POINT: u16 = 15;
    pub const COPY_MEMORY: u16 = 63;
    pub const ATOMIC_F_MIN: u16 = 5614;
    pub const ATOMIC_F_MAX: u16 = 5615;
}

const DECORATION_SPEC_ID: u32 = 1;
const DECORATION_BUILT_IN: u32 = 11;
const BUILT_IN_FRAG_DEPTH: u32 = 22;
const MODE_EARLY_FRAGMENT_TESTS: u32 = 9;
const EXECUTION_MODEL_FRAGMENT: u32 = 4;
/// Storage classes a fragment shader can write memory through: Uniform (a `BufferBlock`,
/// SPIR-V 1.0's storage buffer), Image, StorageBuffer, PhysicalStorageBuffer.
const WRITABLE_CLASSES: [u32; 4] = [2, 11, 12, 5349];
/// Output: the class of `gl_FragDepth`.
const OUTPUT_CLASS: u32 = 3;

/// What one block does and where it goes.
#[derive(Debug, Default)]
struct Block {
    discard: bool,
    depth_write: bool,
    storage_writes: bool,
    calls: Vec<u32>,
    /// Successor labels; `None` entries are not used — a folded branch lists one target.
    next: Vec<u32>,
}

/// The facts of `spirv` (a fragment shader named `name`) under `specialization` ((SpecId,
/// value) pairs; constants not listed keep their defaults).
pub fn fragment_facts(
    name: &str,
    spirv: &[u8],
    specialization: &[(u32, u32)],
) -> Result<FragmentFacts, VkError> {
    let words = spirv_words(name, spirv)?;
    let malformed = |at: usize| VkError::Spirv {
        name: name.to_string(),
        reason: format!("malformed instruction at word {at}"),
    };
    let mut facts = FragmentFacts::default();
    // (function, early fragment tests declared for it)
    let mut early_tests_for: Vec<u32> = Vec::new();
    let mut spec_ids: HashMap<u32, u32> = HashMap::new();
    let mut frag_depth: Vec<u32> = Vec::new();
    let mut values: HashMap<u32, u32> = HashMap::new();
    let mut classes: HashMap<u32, u32> = HashMap::new();
    let mut entry_function = None;
    let mut function_entry: HashMap<u32, u32> = HashMap::new();
    let mut blocks: HashMap<u32, Block> = HashMap::new();
    let mut current_function = None;
    let mut current_block: Option<u32> = None;

    let mut at = 5;
    while at < words.len() {
        let count = (words[at] >> 16) as usize;
        let opcode = (words[at] & 0xffff) as u16;
        let Some(ins) = words.get(at..at + count).filter(|_| count > 0) else {
            return Err(malformed(at));
        };
        let w = |i: usize| ins.get(i).copied().ok_or_else(|| malformed(at));
        match opcode {
            // The fragment entry point (a module may hold several stages).
            op::ENTRY_POINT if w(1)? == EXECUTION_MODEL_FRAGMENT => {
                entry_function = Some(w(2)?);
            }
            op::EXECUTION_MODE if w(2)? == MODE_EARLY_FRAGMENT_TESTS => {
                early_tests_for.push(w(1)?);
            }
            op::DECORATE => match (w(2)?, ins.get(3)) {
                (DECORATION_SPEC_ID, Some(&id)) => {
                    spec_ids.insert(w(1)?, id);
                }
                (DECORATION_BUILT_IN, Some(&BUILT_IN_FRAG_DEPTH)) => frag_depth.push(w(1)?),
                _ => {}
            },
            op::CONSTANT => {
                values.insert(w(2)?, w(3)?);
            }
            op::CONSTANT_TRUE | op::CONSTANT_FALSE => {
                values.insert(w(2)?, u32::from(opcode == op::CONSTANT_TRUE));
            }
            op::SPEC_CONSTANT | op::SPEC_CONSTANT_TRUE | op::SPEC_CONSTANT_FALSE => {
                let id = w(2)?;
                let default = match opcode {
                    op::SPEC_CONSTANT => w(3)?,
                    op::SPEC_CONSTANT_TRUE => 1,
                    _ => 0,
                };
                let value = spec_ids
                    .get(&id)
                    .and_then(|sid| specialization.iter().find(|(s, _)| s == sid))
                    .map_or(default, |&(_, v)| v);
                let value = if opcode == op::SPEC_CONSTANT {
                    value
                } else {
                    u32::from(value != 0)
                };
                values.insert(id, value);
            }
            op::SPEC_CONSTANT_OP => {
                let operands: Option<Vec<u32>> = ins
                    .get(4..)
                    .unwrap_or(&[])
                    .iter()
                    .map(|id| values.get(id).copied())
                    .collect();
                let operation = w(3)? as u16;
                if let Some(v) = operands.and_then(|o| fold(operation, &o)) {
                    values.insert(w(2)?, v);
                }
            }
            op::VARIABLE => {
                classes.insert(w(2)?, w(3)?);
            }
            op::ACCESS_CHAIN | op::IN_BOUNDS_ACCESS_CHAIN | op::PTR_ACCESS_CHAIN => {
                if let Some(&c) = classes.get(&w(3)?) {
                    classes.insert(w(2)?, c);
                }
            }
            op::FUNCTION => {
                current_function = Some(w(2)?);
                current_block = None;
            }
            op::LABEL => {
                let label = w(1)?;
                if let Some(f) = current_function {
                    function_entry.entry(f).or_insert(label);
                }
                blocks.insert(label, Block::default());
                current_block = Some(label);
            }
            _ => {}
        }
        if let Some(block) = current_block.and_then(|b| blocks.get_mut(&b)) {
            match opcode {
                op::KILL | op::TERMINATE_INVOCATION | op::DEMOTE_TO_HELPER_INVOCATION => {
                    block.discard = true;
                }
                op::STORE => {
                    let pointer = w(1)?;
                    let class = classes.get(&pointer).copied();
                    if frag_depth.contains(&pointer) && class == Some(OUTPUT_CLASS) {
                        block.depth_write = true;
                    }
                    if class.is_some_and(|c| WRITABLE_CLASSES.contains(&c)) {
                        block.storage_writes = true;
                    }
                }
                op::COPY_MEMORY
                    if classes
                        .get(&w(1)?)
                        .is_some_and(|c| WRITABLE_CLASSES.contains(c)) =>
                {
                    block.storage_writes = true;
                }
                op::IMAGE_WRITE
                | op::ATOMIC_FLAG_TEST_AND_SET
                | op::ATOMIC_FLAG_CLEAR
                | op::ATOMIC_F_ADD
                | op::ATOMIC_F_MIN
                | op::ATOMIC_F_MAX => block.storage_writes = true,
                o if (op::ATOMIC_STORE..=op::ATOMIC_XOR).contains(&o) => {
                    // Every atomic but OpAtomicLoad writes; a fragment shader's atomics are on
                    // storage buffers or images.
                    block.storage_writes = true;
                }
                op::FUNCTION_CALL => block.calls.push(w(3)?),
                op::BRANCH => block.next.push(w(1)?),
                op::BRANCH_CONDITIONAL => match values.get(&w(1)?) {
                    Some(&v) => block.next.push(if v != 0 { w(2)? } else { w(3)? }),
                    None => block.next.extend([w(2)?, w(3)?]),
                },
                op::SWITCH => {
                    let targets: Vec<(u32, u32)> = ins
                        .get(3..)
                        .unwrap_or(&[])
                        .chunks_exact(2)
                        .map(|c| (c[0], c[1]))
                        .collect();
                    let default = w(2)?;
                    match values.get(&w(1)?) {
                        Some(&v) => block.next.push(
                            targets
                                .iter()
                                .find(|(lit, _)| *lit == v)
                                .map_or(default, |&(_, l)| l),
                        ),
                        None => {
                            block.next.push(default);
                            block.next.extend(targets.iter().map(|&(_, l)| l));
                        }
                    }
                }
                _ => {}
            }
        }
        at += count;
    }
    let _ = op::ATOMIC_LOAD; // the one atomic that does not write (excluded by the range)

    facts.early_fragment_tests = entry_function.is_some_and(|f| early_tests_for.contains(&f));
    // Reachability from the entry point's first block, into called functions.
    let mut seen: HashSet<u32> = HashSet::new();
    let mut work: Vec<u32> = entry_function
        .and_then(|f| function_entry.get(&f).copied())
        .into_iter()
        .collect();
    while let Some(label) = work.pop() {
        if !seen.insert(label) {
            continue;
        }
        let Some(b) = blocks.get(&label) else {
            continue;
        };
        facts.discard |= b.discard;
        facts.depth_write |= b.depth_write;
        facts.storage_writes |= b.storage_writes;
        work.extend(&b.next);
        work.extend(b.calls.iter().filter_map(|f| function_entry.get(f)));
    }
    Ok(facts)
}

/// The value of an `OpSpecConstantOp` over known operands, for the operations a shader's
/// specialization branches use; `None` for any other.
fn fold(opcode: u16, o: &[u32]) -> Option<u32> {
    let b = |x: bool| Some(u32::from(x));
    match (opcode, o) {
        (op::I_EQUAL, [a, c]) | (op::LOGICAL_EQUAL, [a, c]) => b(a == c),
        (op::I_NOT_EQUAL, [a, c]) | (op::LOGICAL_NOT_EQUAL, [a, c]) => b(a != c),
        (op::U_LESS_THAN, [a, c]) => b(a < c),
        (op::U_LESS_THAN_EQUAL, [a, c]) => b(a <= c),
        (op::U_GREATER_THAN, [a, c]) => b(a > c),
        (op::U_GREATER_THAN_EQUAL, [a, c]) => b(a >= c),
        (op::LOGICAL_AND, [a, c]) => b(*a != 0 && *c != 0),
        (op::LOGICAL_OR, [a, c]) => b(*a != 0 || *c != 0),
        (op::LOGICAL_NOT, [a]) => b(*a == 0),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spv(name: &str) -> Vec<u8> {
        let path = format!(
            "{}/../../shaders/spv/{name}.spv",
            env!("CARGO_MANIFEST_DIR")
        );
        std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
    }

    fn facts(name: &str, spec: &[(u32, u32)]) -> FragmentFacts {
        fragment_facts(name, &spv(name), spec).unwrap()
    }

    const NONE: FragmentFacts = FragmentFacts {
        discard: false,
        depth_write: false,
        storage_writes: false,
        early_fragment_tests: false,
    };

    #[test]
    fn the_material_class_decides_whether_the_forward_shaders_discard() {
        for shader in ["forward.frag", "forward_early.frag"] {
            let early = shader == "forward_early.frag";
            for (class, discard) in [(0, false), (1, true), (2, false)] {
                assert_eq!(
                    facts(shader, &[(0, class)]),
                    FragmentFacts {
                        discard,
                        early_fragment_tests: early,
                        ..NONE
                    },
                    "{shader} class {class}"
                );
            }
        }
        // The visibility buffer's alpha switch.
        assert!(!facts("visbuf.frag", &[(0, 0)]).discard);
        assert!(facts("visbuf.frag", &[(0, 1)]).discard);
    }

    #[test]
    fn facts_of_the_other_fragment_shaders() {
        assert_eq!(
            facts("depth_alpha.frag", &[]),
            FragmentFacts {
                discard: true,
                ..NONE
            }
        );
        let counting = FragmentFacts {
            storage_writes: true,
            early_fragment_tests: true,
            ..NONE
        };
        assert_eq!(facts("forward_count.frag", &[(0, 0)]), counting);
        assert_eq!(facts("raster_occlusion.frag", &[]), counting);
        let late = facts("forward_count_late.frag", &[(0, 1)]);
        assert!(late.storage_writes && late.discard && !late.early_fragment_tests);
        assert_eq!(
            facts("raster_occlusion_downsample.frag", &[]),
            FragmentFacts {
                depth_write: true,
                ..NONE
            }
        );
        assert_eq!(facts("triangle.frag", &[]), NONE);
    }

    #[test]
    fn malformed_modules_are_errors_naming_the_shader() {
        let mut bytes = spv("triangle.frag");
        // An instruction claiming more words than the module has.
        let last = bytes.len() - 4;
        bytes[last + 2..].copy_from_slice(&0xffffu16.to_le_bytes());
        let e = fragment_facts("cut.frag", &bytes, &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("cut.frag"), "{e}");
        assert!(fragment_facts("short.frag", &[0; 8], &[]).is_err());
    }
}
