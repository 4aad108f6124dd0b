//! The objects behind the handles. A handle is a 64-bit value — kind, registry, generation,
//! slot — never a pointer: a destroyed handle, one of another kind or one made on another
//! thread is found out by comparing numbers, and C can never make tilegraph dereference freed
//! memory. Each thread has its own registry (a context is used on the thread that made it).
//!
//! Bits: kind (8) | registry (16) | generation (16) | slot (24).

use std::any::Any;
use std::cell::RefCell;
use std::sync::atomic::{AtomicU16, Ordering};

use crate::status::{Failure, TgStatus};

/// What a handle names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Context = 1,
    Scene = 2,
    Renderer = 3,
    Graph = 4,
    Plan = 5,
    Pvs = 6,
}

impl Kind {
    const ALL: [Kind; 6] = [
        Kind::Context,
        Kind::Scene,
        Kind::Renderer,
        Kind::Graph,
        Kind::Plan,
        Kind::Pvs,
    ];

    fn name(self) -> &'static str {
        match self {
            Kind::Context => "TgContext",
            Kind::Scene => "TgScene",
            Kind::Renderer => "TgRenderer",
            Kind::Graph => "TgGraph",
            Kind::Plan => "TgPlan",
            Kind::Pvs => "TgPvs",
        }
    }
}

struct Slot {
    generation: u16,
    kind: Kind,
    /// Objects made from this one and still alive (a context's renderers, a scene's).
    users: u32,
    /// The objects this one was made from (released when it is removed).
    uses: Vec<(u64, Kind)>,
    /// `None` while free, or when an internal panic dropped the object mid-call.
    object: Option<Box<dyn Any>>,
    live: bool,
}

struct Registry {
    id: u16,
    slots: Vec<Slot>,
    free: Vec<u32>,
}

const SLOT_BITS: u32 = 24;

static NEXT_REGISTRY: AtomicU16 = AtomicU16::new(1);

thread_local! {
    static REGISTRY: RefCell<Registry> = RefCell::new(Registry {
        id: NEXT_REGISTRY.fetch_add(1, Ordering::Relaxed).max(1),
        slots: Vec::new(),
        free: Vec::new(),
    });
}

/// A decoded handle.
#[derive(Debug, Clone, Copy)]
struct Parts {
    kind: u8,
    registry: u16,
    generation: u16,
    slot: u32,
}

fn decode(raw: u64) -> Parts {
    Parts {
        kind: (raw >> 56) as u8,
        registry: (raw >> 40) as u16,
        generation: (raw >> 24) as u16,
        slot: (raw & ((1 << SLOT_BITS) - 1)) as u32,
    }
}

fn encode(kind: Kind, registry: u16, generation: u16, slot: u32) -> u64 {
    (kind as u64) << 56 | u64::from(registry) << 40 | u64::from(generation) << 24 | u64::from(slot)
}

impl Registry {
    /// The slot `raw` names, checked: non-zero, of `kind`, of this thread, alive.
    fn slot(&mut self, raw: u64, kind: Kind, name: &str) -> Result<&mut Slot, Failure> {
        let invalid =
            |why: String| Failure::new(TgStatus::InvalidHandle, format!("`{name}` {why}"));
        if raw == 0 {
            return Err(invalid("is a null handle".into()));
        }
        let p = decode(raw);
        let Some(actual) = Kind::ALL.into_iter().find(|k| *k as u8 == p.kind) else {
            return Err(invalid(format!("({raw:#x}) is not a tilegraph handle")));
        };
        if actual != kind {
            return Err(invalid(format!(
                "is a {} handle, not a {}",
                actual.name(),
                kind.name()
            )));
        }
        if p.registry != self.id {
            return Err(invalid(
                "was made on another thread (a context and everything made from it stay on \
                 the thread that made them)"
                    .into(),
            ));
        }
        match self.slots.get_mut(p.slot as usize) {
            Some(s) if s.live && s.generation == p.generation && s.kind == kind => Ok(s),
            _ => Err(invalid(format!("is a {} that was destroyed", kind.name()))),
        }
    }
}

/// Stores `object` and returns its handle.
pub fn insert<T: Any>(kind: Kind, object: T) -> Result<u64, Failure> {
    insert_using(kind, object, &[])
}

/// Stores `object`, made from the objects `uses` names (each validated): they cannot be
/// destroyed while it lives.
pub fn insert_using<T: Any>(
    kind: Kind,
    object: T,
    uses: &[(u64, Kind, &str)],
) -> Result<u64, Failure> {
    REGISTRY.with(|r| {
        let mut r = r.borrow_mut();
        for (raw, kind, name) in uses {
            r.slot(*raw, *kind, name)?;
        }
        for (raw, kind, name) in uses {
            r.slot(*raw, *kind, name)?.users += 1;
        }
        let index = match r.free.pop() {
            Some(i) => i,
            None => {
                let i = r.slots.len() as u32;
                if i >= 1 << SLOT_BITS {
                    return Err(Failure::new(
                        TgStatus::OutOfMemory,
                        format!(
                            "more than {} live handles on this thread",
                            1u32 << SLOT_BITS
                        ),
                    ));
                }
                r.slots.push(Slot {
                    generation: 0,
                    kind,
                    users: 0,
                    uses: Vec::new(),
                    object: None,
                    live: false,
                });
                i
            }
        };
        let id = r.id;
        let slot = &mut r.slots[index as usize];
        slot.generation = slot.generation.wrapping_add(1);
        slot.kind = kind;
        slot.users = 0;
        slot.uses = uses.iter().map(|(raw, kind, _)| (*raw, *kind)).collect();
        slot.object = Some(Box::new(object));
        slot.live = true;
        Ok(encode(kind, id, slot.generation, index))
    })
}

fn lost(name: &str) -> Failure {
    Failure::new(
        TgStatus::InvalidHandle,
        format!("`{name}` lost its object to an internal error in an earlier call; destroy it"),
    )
}

fn downcast<'a, T: Any>(slot: &'a mut Slot, name: &str) -> Result<&'a mut T, Failure> {
    slot.object
        .as_mut()
        .and_then(|o| o.downcast_mut::<T>())
        .ok_or_else(|| lost(name))
}

/// Runs `f` on the object `raw` names (read-only: other handles may be looked up inside).
pub fn with<T: Any, R>(
    raw: u64,
    kind: Kind,
    name: &str,
    f: impl FnOnce(&T) -> Result<R, Failure>,
) -> Result<R, Failure> {
    REGISTRY.with(|r| {
        let mut r = r.borrow_mut();
        let slot = r.slot(raw, kind, name)?;
        let object: &T = downcast(slot, name)?;
        // The registry stays borrowed while `f` runs: `f` looks up no other handle.
        f(object)
    })
}

/// Runs `f` on the objects `a` and `b` name, both read-only.
pub fn with2<A: Any, B: Any, R>(
    (a, a_kind, a_name): (u64, Kind, &str),
    (b, b_kind, b_name): (u64, Kind, &str),
    f: impl FnOnce(&A, &B) -> Result<R, Failure>,
) -> Result<R, Failure> {
    REGISTRY.with(|r| {
        let mut r = r.borrow_mut();
        // Validate both, then borrow both (distinct slots: distinct kinds).
        r.slot(a, a_kind, a_name)?;
        r.slot(b, b_kind, b_name)?;
        let (ia, ib) = (decode(a).slot as usize, decode(b).slot as usize);
        if ia == ib {
            return Err(Failure::invalid(format!(
                "`{a_name}` and `{b_name}` are the same handle"
            )));
        }
        let (first, second) = if ia < ib { (ia, ib) } else { (ib, ia) };
        let (low, high) = r.slots.split_at_mut(second);
        let (sa, sb) = if ia < ib {
            (&low[first], &high[0])
        } else {
            (&high[0], &low[first])
        };
        let oa = sa
            .object
            .as_ref()
            .and_then(|o| o.downcast_ref::<A>())
            .ok_or_else(|| lost(a_name))?;
        let ob = sb
            .object
            .as_ref()
            .and_then(|o| o.downcast_ref::<B>())
            .ok_or_else(|| lost(b_name))?;
        f(oa, ob)
    })
}

/// Takes the object `raw` names out of its slot for a call that also needs other objects;
/// [`put_back`] returns it. A panic in between drops it (the handle then reports it lost).
pub fn take<T: Any>(raw: u64, kind: Kind, name: &str) -> Result<Box<T>, Failure> {
    REGISTRY.with(|r| {
        let mut r = r.borrow_mut();
        let slot = r.slot(raw, kind, name)?;
        let object = slot.object.take().ok_or_else(|| lost(name))?;
        match object.downcast::<T>() {
            Ok(t) => Ok(t),
            Err(other) => {
                slot.object = Some(other);
                Err(lost(name))
            }
        }
    })
}

/// Runs `f` on the object `raw` names, mutably; refused (TG_STATUS_IN_USE) while objects made
/// from it (renderers) exist, since they hold what it was when they were made.
pub fn with_unused_mut<T: Any, R>(
    raw: u64,
    kind: Kind,
    name: &str,
    f: impl FnOnce(&mut T) -> Result<R, Failure>,
) -> Result<R, Failure> {
    REGISTRY.with(|r| {
        let mut r = r.borrow_mut();
        let slot = r.slot(raw, kind, name)?;
        if slot.users > 0 {
            return Err(Failure::new(
                TgStatus::InUse,
                format!(
                    "`{name}` still has {} user(s) (renderers made from it): destroy them first",
                    slot.users
                ),
            ));
        }
        let object: &mut T = downcast(slot, name)?;
        f(object)
    })
}

/// Runs `f` on the object `raw` names, mutably, users or not: for an object its users follow
/// (a scene its renderers read at their next record).
pub fn with_mut<T: Any, R>(
    raw: u64,
    kind: Kind,
    name: &str,
    f: impl FnOnce(&mut T) -> Result<R, Failure>,
) -> Result<R, Failure> {
    REGISTRY.with(|r| {
        let mut r = r.borrow_mut();
        let slot = r.slot(raw, kind, name)?;
        let object: &mut T = downcast(slot, name)?;
        f(object)
    })
}

/// Puts an object taken with [`take`] back.
pub fn put_back<T: Any>(raw: u64, kind: Kind, object: Box<T>) {
    REGISTRY.with(|r| {
        let mut r = r.borrow_mut();
        if let Ok(slot) = r.slot(raw, kind, "handle") {
            slot.object = Some(object);
        }
    });
}

/// Removes the object `raw` names and frees its handle (`Ok(None)`: the object was lost to an
/// internal error; the handle is freed all the same), releasing the objects it was made from.
/// An object with users is refused.
pub fn remove<T: Any>(raw: u64, kind: Kind, name: &str) -> Result<Option<Box<T>>, Failure> {
    REGISTRY.with(|r| {
        let mut r = r.borrow_mut();
        let slot = r.slot(raw, kind, name)?;
        if slot.users > 0 {
            return Err(Failure::new(
                TgStatus::InUse,
                format!(
                    "`{name}` still has {} user(s) (renderers made from it): destroy them first",
                    slot.users
                ),
            ));
        }
        let object = slot.object.take().and_then(|o| o.downcast::<T>().ok());
        slot.live = false;
        let uses = std::mem::take(&mut slot.uses);
        // A slot whose generation would wrap is retired, never reused: a handle destroyed
        // long ago must not name a new object (the `slot_bits` limit bounds the cost).
        let retired = slot.generation == u16::MAX;
        let index = decode(raw).slot;
        if !retired {
            r.free.push(index);
        }
        for (raw, kind) in uses {
            if let Ok(used) = r.slot(raw, kind, "used object") {
                used.users = used.users.saturating_sub(1);
            }
        }
        Ok(object)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_handle_from_another_thread_is_refused_with_the_reason() {
        let raw = insert(Kind::Scene, 7u32).unwrap();
        let elsewhere =
            std::thread::spawn(move || with(raw, Kind::Scene, "scene", |v: &u32| Ok(*v)))
                .join()
                .unwrap();
        let err = elsewhere.unwrap_err();
        assert_eq!(err.status, TgStatus::InvalidHandle);
        assert!(err.message.contains("another thread"), "{}", err.message);
        assert_eq!(
            with(raw, Kind::Scene, "scene", |v: &u32| Ok(*v)).unwrap(),
            7
        );
    }

    #[test]
    fn a_reused_slot_does_not_revive_the_old_handle() {
        let old = insert(Kind::Plan, 1u8).unwrap();
        remove::<u8>(old, Kind::Plan, "plan").unwrap();
        let new = insert(Kind::Plan, 2u8).unwrap();
        assert_eq!(decode(old).slot, decode(new).slot, "the slot is reused");
        let err = with(old, Kind::Plan, "plan", |v: &u8| Ok(*v)).unwrap_err();
        assert!(err.message.contains("destroyed"), "{}", err.message);
        assert_eq!(with(new, Kind::Plan, "plan", |v: &u8| Ok(*v)).unwrap(), 2);
    }

    #[test]
    fn a_slot_is_retired_before_its_generation_wraps() {
        // Each test runs on a thread of its own: this registry is the test's.
        let first = insert(Kind::Plan, 0u8).unwrap();
        let slot = decode(first).slot;
        remove::<u8>(first, Kind::Plan, "plan").unwrap();
        let mut last = first;
        for _ in 1..u16::MAX {
            last = insert(Kind::Plan, 0u8).unwrap();
            assert_eq!(decode(last).slot, slot, "the one slot is reused");
            remove::<u8>(last, Kind::Plan, "plan").unwrap();
        }
        assert_eq!(decode(last).generation, u16::MAX);
        let next = insert(Kind::Plan, 0u8).unwrap();
        assert_ne!(
            decode(next).slot,
            slot,
            "a slot at the last generation is not reused"
        );
        let err = with(first, Kind::Plan, "plan", |v: &u8| Ok(*v)).unwrap_err();
        assert!(err.message.contains("destroyed"), "{}", err.message);
    }
}
