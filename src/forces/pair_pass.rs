//! The pair pass: every touching pair's contact laws, once per pair, added to both particles.
//!
//! A coloured traversal of the neighbour list slab by slab
//! ([`NeighborList::for_each_slab_near`]). Each slab visit *sifts* its candidates (every slot
//! where it records its near list, the near list otherwise) for the pairs that need work,
//! copies the touching ones into the lanes of a batch (`handle_kept`), runs the vectorised laws
//! over a full batch (`lanes::run`) and writes the results back in the list's order
//! ([`Batch::flush`]): each contact's shares added to its two particles at once, so every sum
//! is formed in the list's order, whatever the thread count. The targets are opened per visit
//! ([`Scatter::open`]), so the writes check their bounds once per visit.

use std::ops::Range;

use glam::DVec3;

use super::lanes::{self, ContactLanes, LANES, PairMaterial};
use super::{ForceSummary, ParticleReads, pair_separation};
use crate::contact::BondState;
use crate::contact::tangential::TangentialSpring;
use crate::model::Model;
use crate::neighbor::{NearPairs, NeighborList};
use crate::pair_history::{HistoryTargets, OpenHistories, Pool};
use crate::particles::Particles;
use crate::periodic::Periodic;
use crate::scatter::{
    Member, NearTokens, Opened, OpenedReads, PerParticle, PerSlot, Scatter, SlabVisit, Slot, Window,
};
use crate::simd::InstructionSet;
use crate::thermal::ThermalModel;

/// What the pair pass writes, shared by the concurrent slabs of a colour phase.
pub(super) struct PairTargets<'a> {
    pub(super) force: Scatter<'a, DVec3, PerParticle>,
    pub(super) lost: Scatter<'a, f64, PerParticle>,
    /// Per slot, with a bond law in the scene.
    pub(super) states: Option<Scatter<'a, BondState, PerSlot>>,
    pub(super) torque: Option<Scatter<'a, DVec3, PerParticle>>,
    pub(super) tangential: Option<HistoryTargets<'a>>,
    pub(super) heat: Option<HeatTargets<'a>>,
}

/// The thermal part of [`PairTargets`], with the inputs the conductances need.
pub(super) struct HeatTargets<'a> {
    pub(super) model: &'a ThermalModel,
    pub(super) melted: &'a [bool],
    pub(super) temperature: &'a [f64],
    pub(super) sums: Scatter<'a, f64, PerParticle>,
    /// At a step whose largest heat rate is taken: each particle's total conductance G_i.
    pub(super) totals: Option<Scatter<'a, f64, PerParticle>>,
}

impl PairTargets<'_> {
    /// The targets for the tokens of `visit` alone, with the physics of one compiled pass:
    /// those it leaves out are `None`.
    #[inline(always)]
    fn open<'t, 'v, const BONDS: bool, const FRICTION: bool, const HEAT: bool>(
        &'t self,
        visit: &SlabVisit<'v>,
    ) -> OpenTargets<'t, 'v> {
        OpenTargets {
            force: self.force.open(visit),
            lost: self.lost.open(visit),
            states: self
                .states
                .as_ref()
                .filter(|_| BONDS)
                .map(|s| s.open(visit)),
            torque: self
                .torque
                .as_ref()
                .filter(|_| FRICTION)
                .map(|t| t.open(visit)),
            tangential: self
                .tangential
                .as_ref()
                .filter(|_| FRICTION)
                .map(|h| h.open(visit)),
            heat: self.heat.as_ref().filter(|_| HEAT).map(|h| OpenHeat {
                model: h.model,
                melted: OpenedReads::open(h.melted, visit),
                temperature: OpenedReads::open(h.temperature, visit),
                sums: h.sums.open(visit),
                totals: h.totals.as_ref().map(|t| t.open(visit)),
            }),
        }
    }
}

/// [`PairTargets`] opened for one slab visit ([`Scatter::open`]): its tokens write them without
/// a bounds check per access. What the compiled pass leaves out is `None`.
struct OpenTargets<'t, 'v> {
    force: Opened<'t, 'v, DVec3, PerParticle>,
    lost: Opened<'t, 'v, f64, PerParticle>,
    states: Option<Opened<'t, 'v, BondState, PerSlot>>,
    torque: Option<Opened<'t, 'v, DVec3, PerParticle>>,
    tangential: Option<OpenHistories<'t, 'v>>,
    heat: Option<OpenHeat<'t, 'v>>,
}

/// [`HeatTargets`] opened for one slab visit.
struct OpenHeat<'t, 'v> {
    model: &'t ThermalModel,
    melted: OpenedReads<'t, 'v, bool>,
    temperature: OpenedReads<'t, 'v, f64>,
    sums: Opened<'t, 'v, f64, PerParticle>,
    totals: Option<Opened<'t, 'v, f64, PerParticle>>,
}

/// The pair pass over every slab, compiled for one combination of optional physics: bond
/// states (`BONDS`), tangential springs and torques (`FRICTION`), conduction (`HEAT`). A target
/// the combination leaves out is ignored even if present. A slab visit that records its near
/// list sifts every slot of its owners; the others sift their near lists only. The contacts act
/// over `interval` \[s\] (`forces::Evaluation::interval`), with the laws built for `set`.
#[allow(clippy::too_many_arguments)]
pub(super) fn run<const BONDS: bool, const FRICTION: bool, const HEAT: bool>(
    model: &Model,
    particles: &Particles,
    list: &NeighborList,
    (near, refresh_near): (&mut NearPairs, bool),
    omega: Option<&[DVec3]>,
    targets: &PairTargets<'_>,
    (set, interval): (InstructionSet, f64),
    parallel: bool,
) -> ForceSummary {
    let _pass = crate::team::PassName::enter("pair pass");
    let near_skin = near.skin(list);
    let prefetch = super::worth_prefetching(particles.len());
    list.for_each_slab_near(
        parallel,
        near,
        refresh_near,
        ForceSummary::default(),
        |summary, slab| {
            let targets = &targets.open::<BONDS, FRICTION, HEAT>(slab);
            let reads = ParticleReads::open(particles, omega.filter(|_| FRICTION), slab);
            let thermal = targets.heat.as_ref().map(|h| h.model);
            let mut batch = Batch::new(model, thermal, interval, slab);
            if slab.records_near() {
                for window in slab.windows() {
                    sift::<BONDS, FRICTION>(model, reads, targets, &window, near_skin, &mut batch);
                    if batch.kept.len() >= KEPT_PER_ROUND {
                        handle_kept::<BONDS, FRICTION, HEAT>(
                            model, reads, targets, &mut batch, set, summary,
                        );
                    }
                }
            } else {
                let count = slab.near_count();
                for start in (0..count).step_by(NEAR_PER_ROUND) {
                    let entries = (slab, start..(start + NEAR_PER_ROUND).min(count));
                    // Two builds of the sift: the test of `prefetch` stays out of its loop.
                    if prefetch {
                        sift_near::<BONDS, FRICTION, HEAT, true>(
                            model, reads, targets, entries, &mut batch,
                        );
                    } else {
                        sift_near::<BONDS, FRICTION, HEAT, false>(
                            model, reads, targets, entries, &mut batch,
                        );
                    }
                    handle_kept::<BONDS, FRICTION, HEAT>(
                        model, reads, targets, &mut batch, set, summary,
                    );
                }
            }
            handle_kept::<BONDS, FRICTION, HEAT>(model, reads, targets, &mut batch, set, summary);
            // The springs the visit did not meet belong to pairs that came apart.
            if let Some(histories) = targets.tangential.as_ref().filter(|_| FRICTION) {
                release_unmet(slab, histories, &targets.lost);
            }
            batch.flush::<BONDS, FRICTION, HEAT>(model, reads, targets, set, summary);
            batch.release_buffers();
        },
        ForceSummary::merge,
    )
}

/// Near-list entries sifted before their kept slots are handled: about a hundred kept slots, as
/// [`KEPT_PER_ROUND`] owners give when all slots are sifted.
const NEAR_PER_ROUND: usize = 256;

/// How many near entries ahead of its test the sift asks for a partner's position and radius,
/// where it prefetches ([`super::worth_prefetching`]): on the 97.2k LIGGGHTS bed at 1 thread on
/// a Zen 3 host, 16 made the step 1.03 times faster (4 alternating pairs, 1.011-1.033), 32 no
/// faster than 16 (docs/performance-log.md, thirty-fifth round). The first entries of each round
/// of [`NEAR_PER_ROUND`] go without: the round's iterator does not reach into the next.
const SIFT_AHEAD: usize = 16;

/// Appends the near-list entries `range` of `slab` that need work to the batch's kept slots, as
/// [`sift`] does for a window's slots: without a branch on whether a pair touches. The owner
/// changes from entry to entry here, so its position is loaded each time (it is in cache: the
/// entries come owner by owner). The entries whose separation needs the minimum image are
/// taken one by one between the runs of those that do not ([`NearList`]), so that the runs'
/// loop tests no image flag.
#[inline(always)]
fn sift_near<
    's,
    const BONDS: bool,
    const FRICTION: bool,
    const HEAT: bool,
    const PREFETCH: bool,
>(
    model: &Model,
    reads: ParticleReads<'_, 's>,
    targets: &OpenTargets<'_, 's>,
    (slab, range): (&SlabVisit<'s>, Range<usize>),
    batch: &mut Batch<'_, 's>,
) {
    // Known at compile time to be `None` where the instantiation leaves the physics out.
    let states = targets.states.as_ref().filter(|_| BONDS);
    // With `PREFETCH`, the entries `SIFT_AHEAD` places on, whose partners' lines are asked for.
    let mut ahead = slab.near_pairs(range.clone()).skip(SIFT_AHEAD);
    // The slot of an entry and whether it needs work, its separation by the image rule of
    // `periodic` (`None` for the plain difference).
    let mut offer = |entry: NearTokens<'s>, periodic: Option<&Periodic>| {
        let NearTokens {
            owner,
            slot,
            partner,
        } = entry;
        if PREFETCH {
            prefetch_partner::<FRICTION, HEAT>(reads, targets, partner);
            if let Some(next) = ahead.next() {
                reads.position.prefetch(next.partner);
                reads.radius.prefetch(next.partner);
            }
        }
        let separation = pair_separation(
            periodic,
            reads.position.get(owner),
            reads.position.get(partner),
        );
        let reach = reads.radius.get(owner) + reads.radius.get(partner);
        let touching = separation.length_squared() < reach * reach;
        let kept_slot = KeptSlot {
            owner,
            partner,
            slot,
            separation,
        };
        (kept_slot, needs_work(touching, slot, states))
    };
    let mut start = range.start;
    for &crossing in slab.near_crossing(range.clone()) {
        let crossing = crossing as usize;
        let run = slab.near_pairs(start..crossing);
        batch
            .kept
            .sift(run, crossing - start, |entry| offer(entry, None));
        let image = slab.near_pairs(crossing..crossing + 1);
        batch
            .kept
            .sift(image, 1, |entry| offer(entry, model.periodic.as_ref()));
        start = crossing + 1;
    }
    let run = slab.near_pairs(start..range.end);
    batch
        .kept
        .sift(run, range.end - start, |entry| offer(entry, None));
}

/// The touching pair in a lane of the batch: whom the write-back ([`Batch::flush`]) adds the
/// lane's results to.
#[derive(Debug, Clone, Copy)]
struct LanePair<'s> {
    owner: Member<'s>,
    partner: Member<'s>,
    slot: Slot<'s>,
}

/// The pairs of a batch's lanes ([`LanePair`]), by column: one array per part, so that the
/// fill stores a lane's pair and the write-back loads it at the lane's index, without the
/// multiplication by the 12-byte record's size (three instructions per contact). On the 19.2k
/// LIGGGHTS bed: 346.4 → 342.5 instructions per particle-step (docs/performance-log.md,
/// sixty-third round).
#[derive(Debug, Clone, Copy)]
struct LanePairs<'s> {
    owner: [Member<'s>; LANES],
    partner: [Member<'s>; LANES],
    slot: [Slot<'s>; LANES],
}

impl<'s> LanePairs<'s> {
    /// Every lane's pair `pair`.
    fn all(pair: LanePair<'s>) -> Self {
        Self {
            owner: [pair.owner; LANES],
            partner: [pair.partner; LANES],
            slot: [pair.slot; LANES],
        }
    }

    #[inline(always)]
    fn set(&mut self, lane: usize, pair: LanePair<'s>) {
        self.owner[lane] = pair.owner;
        self.partner[lane] = pair.partner;
        self.slot[lane] = pair.slot;
    }

    /// The pairs of the first `filled` lanes, in order.
    #[inline(always)]
    fn first(&self, filled: usize) -> impl Iterator<Item = LanePair<'s>> + '_ {
        let (owner, partner, slot) = (
            &self.owner[..filled],
            &self.partner[..filled],
            &self.slot[..filled],
        );
        owner
            .iter()
            .zip(partner)
            .zip(slot)
            .map(|((&owner, &partner), &slot)| LanePair {
                owner,
                partner,
                slot,
            })
    }
}

/// A slab's contacts on their way through the kernel: the lanes being filled and their pairs.
struct Batch<'r, 's> {
    slab: &'r SlabVisit<'s>,
    /// The time the contacts act over \[s\]: the step's dt, 0 at the set-up evaluation.
    interval: f64,
    lanes: ContactLanes,
    /// The pairs of the first `filled` lanes ([`handle_kept`]); `None` until the visit's
    /// first contact, whose pair the others start as (the tokens have no value of their own).
    pairs: Option<LanePairs<'s>>,
    filled: usize,
    /// The slots that need work, of the owners sifted since the last [`handle_kept`], in order.
    kept: KeptSlots<'s>,
}

/// A slot that needs work: touching, or holding a bond state or a spring.
#[derive(Debug, Clone, Copy)]
struct KeptSlot<'s> {
    owner: Member<'s>,
    partner: Member<'s>,
    slot: Slot<'s>,
    /// x_b − x_a \[m\], as the sift found it (its minimum image where the owner needs one):
    /// handling the slot does not load the two positions again.
    separation: DVec3,
}

/// The kept slots of a batch, in order, in a vector whose spare room the sifts write into
/// ([`KeptSlots::sift`]).
struct KeptSlots<'s>(Vec<KeptSlot<'s>>);

impl<'s> KeptSlots<'s> {
    /// Offers each of the first `room` items of `items` (all of them if fewer): `offer` gives
    /// the item's slot and whether it needs work; the slots that do are appended, in order.
    ///
    /// Without a branch on whether a slot needs work, which is a coin toss for the branch
    /// predictor (about one candidate in five touches on a packed bed): every slot is written
    /// at the end of the kept ones, in the room reserved beforehand, and kept by counting it.
    /// The room is reserved once per call and not initialised, and the writes test no bounds:
    /// the vector's initialised scratch, grown by copies of a sample slot, cost the sifts a
    /// bounds check per candidate and each slab visit the sample's copies (6.1 of the 19.2k
    /// LIGGGHTS bed's 95.4 sift instructions per particle-step, docs/performance-log.md,
    /// sixty-fourth round).
    #[inline(always)]
    #[allow(unsafe_code)]
    fn sift<I: Iterator>(
        &mut self,
        items: I,
        room: usize,
        mut offer: impl FnMut(I::Item) -> (KeptSlot<'s>, bool),
    ) {
        let kept = &mut self.0;
        kept.reserve(room);
        let start = kept.len();
        let base = kept.as_mut_ptr();
        let mut count = start;
        // At most `room` items, whatever `items` holds: then `count < start + room`.
        for (item, _) in items.zip(0..room) {
            let (slot, needs_work) = offer(item);
            // SAFETY: `count` grew by at most one per item before this one, of which there were
            // fewer than `room`, so `count < start + room`, within the capacity reserved above.
            unsafe { base.add(count).write(slot) };
            count += usize::from(needs_work);
        }
        // SAFETY: the slots below `start` were initialised, and `count` only ever passed a
        // place written just before; `count` is within the capacity (above).
        unsafe { kept.set_len(count) };
    }

    /// The number of kept slots.
    fn len(&self) -> usize {
        self.0.len()
    }
}

/// Owners' kept slots gathered before they are handled. Handling many owners' slots in one loop,
/// rather than each owner's in its own, spares the branch predictor a loop exit per owner, which
/// it cannot foresee (an owner has 0-3 contacts).
const KEPT_PER_ROUND: usize = 64;

/// The buffers of a [`Batch`] between slab visits, empty, kept per thread: a visit takes them
/// over instead of allocating its own (with two threads, the allocator's locks and the frees of
/// another thread's blocks cost 3 % of the step). Their elements hold a visit's tokens, so an
/// empty buffer changes its element type's lifetime on the way in and out ([`recycle`]).
#[derive(Default)]
struct BatchBuffers {
    kept: Vec<KeptSlot<'static>>,
}

thread_local! {
    static BATCH_BUFFERS: std::cell::RefCell<BatchBuffers> =
        std::cell::RefCell::new(BatchBuffers::default());
}

/// An empty vector of `T` as one of `U`, of the same size and alignment: the standard library
/// collects a vector's `into_iter().map(..)` into the vector's own allocation then, so the
/// capacity carries over (if it did not, the buffer would only be allocated anew).
fn recycle<T, U>(mut empty: Vec<T>) -> Vec<U> {
    debug_assert_eq!(std::mem::size_of::<T>(), std::mem::size_of::<U>());
    debug_assert_eq!(std::mem::align_of::<T>(), std::mem::align_of::<U>());
    empty.clear();
    empty
        .into_iter()
        .map(|_| unreachable!("the vector is empty"))
        .collect()
}

impl<'r, 's> Batch<'r, 's> {
    /// A batch for the visit of `slab` with `model`'s contacts acting over `interval` \[s\]
    /// and, with conduction, the pass's `thermal` model; with this thread's buffers.
    fn new(
        model: &Model,
        thermal: Option<&ThermalModel>,
        interval: f64,
        slab: &'r SlabVisit<'s>,
    ) -> Self {
        let buffers = BATCH_BUFFERS.with_borrow_mut(std::mem::take);
        Self {
            slab,
            interval,
            lanes: ContactLanes::for_model(model, thermal),
            pairs: None,
            filled: 0,
            kept: KeptSlots(recycle(buffers.kept)),
        }
    }

    /// Gives the buffers back to the thread, for its next visit.
    fn release_buffers(self) {
        let buffers = BatchBuffers {
            kept: recycle(self.kept.0),
        };
        BATCH_BUFFERS.with_borrow_mut(|held| *held = buffers);
    }

    /// Runs the laws of the filled lanes and writes their results back ([`write_lanes`]).
    #[inline]
    fn flush<const BONDS: bool, const FRICTION: bool, const HEAT: bool>(
        &mut self,
        model: &Model,
        reads: ParticleReads<'_, 's>,
        targets: &OpenTargets<'_, 's>,
        set: InstructionSet,
        summary: &mut ForceSummary,
    ) {
        let filled = std::mem::take(&mut self.filled);
        // `None` until the visit's first contact: then nothing was filled.
        let Some(pairs) = &self.pairs else {
            return;
        };
        let histories = targets.tangential.as_ref().filter(|_| FRICTION);
        let interval = self.interval;
        OpenHistories::with_own_or_empty(histories, self.slab.own_slab(), |springs| {
            let lanes = (&mut self.lanes, pairs, filled, springs);
            write_lanes::<BONDS, FRICTION, HEAT>(
                model, reads, targets, lanes, interval, set, summary,
            );
        });
    }
}

/// [`write_lanes_with`], then at a step whose largest heat rate is taken (`PassHeat::totals`)
/// each contact's conductance added to both particles' total conductances G_i, in a loop of its
/// own: the other steps' write-back holds nothing more, and tests nothing more per contact.
#[inline]
fn write_lanes<'s, const BONDS: bool, const FRICTION: bool, const HEAT: bool>(
    model: &Model,
    reads: ParticleReads<'_, 's>,
    targets: &OpenTargets<'_, 's>,
    (lanes, pairs, filled, springs): (&mut ContactLanes, &LanePairs<'s>, usize, &mut Pool),
    interval: f64,
    set: InstructionSet,
    summary: &mut ForceSummary,
) {
    write_lanes_with::<BONDS, FRICTION, HEAT>(
        model,
        reads,
        targets,
        (&mut *lanes, pairs, filled, springs),
        interval,
        set,
        summary,
    );
    let totals = targets.heat.as_ref().filter(|_| HEAT);
    if let Some(totals) = totals.and_then(|h| h.totals.as_ref()) {
        for (lane, pair) in pairs.first(filled).enumerate() {
            let conductance = lanes.conductance(lane);
            totals.update(pair.owner, |g| g + conductance);
            totals.update(pair.partner, |g| g + conductance);
        }
    }
}

/// Runs the laws of the filled `lanes`, whose pairs are `pairs` (one per filled lane), over
/// `interval` \[s\], and writes their results back lane by lane, in the order the pairs were
/// found: each contact's shares to both particles at once, the owner's and then the partner's,
/// as a serial loop over the pairs would add them, and with tangential springs each contact's
/// new spring appended to the visit's `springs`. A function of the lanes, their pairs and the
/// springs rather than of the batch, so that the fill ([`handle_kept`]) keeps the pairs and
/// the springs' cursor in hand across a flush.
#[inline(always)]
fn write_lanes_with<'s, const BONDS: bool, const FRICTION: bool, const HEAT: bool>(
    model: &Model,
    reads: ParticleReads<'_, 's>,
    targets: &OpenTargets<'_, 's>,
    (lanes, pairs, filled, springs): (&mut ContactLanes, &LanePairs<'s>, usize, &mut Pool),
    interval: f64,
    set: InstructionSet,
    summary: &mut ForceSummary,
) {
    // Every filled lane is a touching pair, met once.
    summary.pair_contacts += filled;
    // A pass compiled with conduction has its heat targets (`forces::compute` chooses the
    // build by them): `Some` known at compile time, so the loop tests nothing per contact (the
    // option was loaded from the stack and tested at every contact).
    let heat =
        HEAT.then(|| (targets.heat.as_ref()).expect("a pass with conduction without heat targets"));
    if filled > 0 {
        lanes::run::<BONDS, FRICTION>(set, model, interval, lanes);
        if let Some(h) = heat {
            if !lanes.uniform_material() {
                for (lane, pair) in pairs.first(filled).enumerate() {
                    let [a, b] = [pair.owner, pair.partner].map(|p| reads.material.get(p));
                    lanes.set_conductivities(lane, h.model.pair_conductivities(a, b));
                }
            }
            lanes.run_conductances(set, h.model.conduction);
        }
    }
    let states = targets.states.as_ref().filter(|_| BONDS);
    // With friction the particles rotate (`forces::compute` passes torques and springs
    // together): `Some` known at compile time, so the loop tests nothing per contact.
    let torque =
        FRICTION.then(|| (targets.torque.as_ref()).expect("tangential springs without torques"));
    // Room for the round's springs, made only where the pass has friction (`None` known at
    // compile time without it, as `torque`).
    let mut room = FRICTION.then(|| springs.room(filled));
    let mut max_conductance_per_mass = summary.heat_rate_bound.contact_conductance_per_mass;
    for (lane, pair) in pairs.first(filled).enumerate() {
        let LanePair {
            owner,
            partner,
            slot,
        } = pair;
        // Each output read where it is used, not all at once (`lanes::OutputOf`).
        let out = lanes.output_of(lane);
        let [r_a, r_b] = lanes.radii(lane);
        let state_before = lanes.state_before(lane);
        summary.observe_overlap_at(out.overlap_ratio(), || {
            if r_a <= r_b { owner } else { partner }.index()
        });
        if let Some(states) = states {
            let state = out.state();
            if state != state_before {
                states.write(slot, state);
            }
        }
        if FRICTION {
            if let Some(torque) = torque {
                let [on_a, on_b] = out.torques();
                torque.update(owner, |t| t + on_a);
                torque.update(partner, |t| t + on_b);
            }
        }
        let force_on_a = out.force_on_a();
        targets.force.update(owner, |f| f + force_on_a);
        targets.force.update(partner, |f| f - force_on_a);
        let half_lost = 0.5 * out.lost();
        targets.lost.update(owner, |l| l + half_lost);
        targets.lost.update(partner, |l| l + half_lost);
        if let Some(h) = heat {
            let conductance = lanes.conductance(lane);
            let flow = conductance * (h.temperature.get(partner) - h.temperature.get(owner));
            h.sums.update(owner, |q| q + flow);
            h.sums.update(partner, |q| q - flow);
            // One compare (`maxsd`), where `f64::max` takes four instructions to order a NaN,
            // which `>` passes over as `f64::max` does.
            let per_mass = lanes.conductance_per_mass(lane);
            if per_mass > max_conductance_per_mass {
                max_conductance_per_mass = per_mass;
            }
        }
        // The spring last: its pool's bookkeeping then holds no particle index across it.
        if let Some(room) = room.as_mut() {
            room.write(slot, out.spring());
        }
    }
    summary.heat_rate_bound.contact_conductance_per_mass = max_conductance_per_mass;
}

/// The spring of `slot`, whose pair came apart: it vanishes with the contact (k_t → 0 as δ → 0),
/// and what it held is lost, half to each particle, at once: the lost energy is a record, which
/// no law reads back.
#[inline]
fn release<'s>(
    slab: &SlabVisit<'s>,
    lost: &Opened<'_, 's, f64, PerParticle>,
    slot: u32,
    spring: TangentialSpring,
) {
    if spring.spring_energy != 0.0 {
        let (owner, partner) = slab.pair_of_slot(slot);
        let half = 0.5 * spring.spring_energy;
        lost.update(owner, |l| l + half);
        lost.update(partner, |l| l + half);
    }
}

/// At the end of `slab`'s visit, releases each spring of its slab's pool the visit did not meet
/// ([`release`]): their pairs came apart. Out of line: it runs once per visit, and inlined its
/// pool's cursor took registers from the sift's loop (one more load per near entry).
#[inline(never)]
fn release_unmet<'s>(
    slab: &SlabVisit<'s>,
    histories: &OpenHistories<'_, 's>,
    lost: &Opened<'_, 's, f64, PerParticle>,
) {
    histories.with_own(slab.own_slab(), |springs| {
        springs.release_unmet(|slot, spring| release(slab, lost, slot, spring));
    });
}

/// Appends the window owner's slots that need work to the batch's kept slots: those touching,
/// and those apart that still hold a bond state or a spring. Most candidates are neither, and
/// whether one touches is a coin toss for the branch predictor (about one in five does on a
/// packed bed): the slots are sifted without a branch, each written to the list and kept by
/// advancing its end. The slots whose gap is below `near_skin` go into the slab's near list
/// (this sift runs only where the visit records it).
#[inline(always)]
fn sift<'s, const BONDS: bool, const FRICTION: bool>(
    model: &Model,
    reads: ParticleReads<'_, 's>,
    targets: &OpenTargets<'_, 's>,
    window: &Window<'s>,
    near_skin: f64,
    batch: &mut Batch<'_, 's>,
) {
    // Known at compile time to be `None` where the instantiation leaves the physics out.
    let states = targets.states.as_ref().filter(|_| BONDS);
    let owner = window.owner();
    let minimum_image = window.needs_minimum_image();
    let (x_a, r_a) = (reads.position.get(owner), reads.radius.get(owner));
    // One loop per image rule, so that the rule is not tested per slot.
    let slots = SiftedWindow {
        window,
        slab: batch.slab,
        states,
        x_a,
        r_a,
        near_skin,
    };
    match model.periodic.as_ref().filter(|_| minimum_image) {
        Some(periodic) => slots.sift(reads, &mut batch.kept, |plain| {
            let separation = periodic.minimum_image(plain);
            (separation, separation != plain)
        }),
        None => slots.sift(reads, &mut batch.kept, |plain| (plain, false)),
    }
}

/// What [`sift`] needs of one window.
struct SiftedWindow<'w, 's, 't> {
    window: &'w Window<'s>,
    slab: &'w SlabVisit<'s>,
    states: Option<&'t Opened<'t, 's, BondState, PerSlot>>,
    x_a: DVec3,
    r_a: f64,
    near_skin: f64,
}

impl<'s> SiftedWindow<'_, 's, '_> {
    /// Appends the slots that need work to `kept` and records the near ones; `image` maps
    /// `x_b − x_a` to the separation and whether it differs (the slot crosses a periodic face).
    #[inline(always)]
    fn sift(
        &self,
        reads: ParticleReads<'_, 's>,
        kept: &mut KeptSlots<'s>,
        image: impl Fn(DVec3) -> (DVec3, bool),
    ) {
        let owner = self.window.owner();
        let room = self.window.slot_count();
        kept.sift(self.window.pairs(), room, |(slot, partner)| {
            let (separation, crossing) = image(reads.position.get(partner) - self.x_a);
            let reach = self.r_a + reads.radius.get(partner);
            let distance_squared = separation.length_squared();
            let touching = distance_squared < reach * reach;
            let kept_slot = KeptSlot {
                owner,
                partner,
                slot,
                separation,
            };
            let near_reach = reach + self.near_skin;
            if distance_squared < near_reach * near_reach {
                self.slab.record_near(self.window, slot, crossing);
            }
            (kept_slot, needs_work(touching, slot, self.states))
        });
    }
}

/// The rule of both sifts ([`sift`], [`sift_near`]): a slot needs work if its pair touches or
/// the slot holds a bond state (which must be cleared when it comes apart). (A spring needs no
/// test here: the springs of pairs that came apart are the ones the pass does not meet,
/// [`OpenHistories`].)
#[inline(always)]
fn needs_work<'s>(
    touching: bool,
    slot: Slot<'s>,
    states: Option<&Opened<'_, 's, BondState, PerSlot>>,
) -> bool {
    let bonded = states.is_some_and(|states| states.read(slot) != BondState::Unbonded);
    touching | bonded
}

/// The kept slots of the batch, in order: the pairs apart have their slot state cleared at once;
/// the touching ones go into the batch's lanes, which run and are written back whenever they are
/// full.
#[allow(clippy::too_many_arguments)]
#[inline]
fn handle_kept<'s, const BONDS: bool, const FRICTION: bool, const HEAT: bool>(
    model: &Model,
    reads: ParticleReads<'_, 's>,
    targets: &OpenTargets<'_, 's>,
    batch: &mut Batch<'_, 's>,
    set: InstructionSet,
    summary: &mut ForceSummary,
) {
    // Known at compile time to be `None` where the instantiation leaves the physics out.
    let states = targets.states.as_ref().filter(|_| BONDS);
    // With friction the particles rotate: the pass has their angular velocities, `Some` known
    // at compile time, so the loop tests nothing per contact (a flag held on the stack was
    // loaded and tested at every contact).
    let omega = FRICTION
        .then(|| (reads.angular_velocity).expect("tangential springs without angular velocities"));
    // `Some` known at compile time where the pass has conduction, as in `write_lanes`.
    let melted = HEAT.then(|| {
        (targets.heat.as_ref())
            .expect("a pass with conduction without heat targets")
            .melted
    });
    let slab = batch.slab;
    let uniform = batch.lanes.uniform_material();
    let Some(&first) = batch.kept.0.first() else {
        return;
    };
    // The round's state in registers, not reloaded from the batch for every contact (the lane
    // count and the lanes' pairs were loaded, tested and stored each time): the lane count, and
    // the batch's fields borrowed one by one, so that a flush needs no `&mut` of the whole.
    // The pairs start as the first kept pair (the tokens have no value of their own).
    let pairs = batch.pairs.get_or_insert(LanePairs::all(LanePair {
        owner: first.owner,
        partner: first.partner,
        slot: first.slot,
    }));
    let lanes = &mut batch.lanes;
    let interval = batch.interval;
    let histories = targets.tangential.as_ref().filter(|_| FRICTION);
    // The springs' cursor in hand for the round too: the slab's pool taken out of the
    // histories for the round (through the histories, its positions and counts were loaded and
    // stored at every contact). Taken per round, not kept in the batch for the visit: moved in
    // and out of the batch, it cost a `memcpy` per round (1.1 instructions per particle-step of
    // the 19.2k LIGGGHTS bed, fifty-ninth round). The walk is a `move` closure over the round's
    // borrows: capturing the batch's fields through the batch cost the fill 0.6 instructions per
    // particle-step of that bed (sixtieth round).
    let kept = batch.kept.0.as_slice();
    let mut filled = batch.filled;
    batch.filled = OpenHistories::with_own_or_empty(histories, slab.own_slab(), move |springs| {
        for &KeptSlot {
            owner,
            partner,
            slot: p,
            separation,
        } in kept
        {
            let (r_a, r_b) = (reads.radius.get(owner), reads.radius.get(partner));
            let reach = r_a + r_b;
            // Without bond states the sifts keep only the touching pairs, by this very test (the
            // same operations on the same values): it is tested again only where a bonded pair
            // apart may have been kept.
            let apart = separation.length_squared() >= reach * reach;
            debug_assert!(BONDS || !apart, "a pair apart kept without bond states");
            if BONDS && apart {
                // Apart: no square root, no division, and the slot's state cleared.
                if let Some(states) = states {
                    if states.read(p) != BondState::Unbonded {
                        states.write(p, BondState::Unbonded);
                    }
                }
                continue;
            }
            debug_assert!(
                model
                    .periodic
                    .is_none_or(|p| p.minimum_image(separation) == separation),
                "a touching pair of owner {} across a periodic face, which the list did not flag",
                owner.index()
            );
            // The lane's parts are stored as they come, so that few values stay live across the
            // spring's look-up (built whole, the input was held in registers and on the stack).
            // Below `LANES` (a full round is flushed at once); the mask says so to the compiler,
            // which then checks no lane index.
            let lane = filled % LANES;
            // The pair first, and the angular velocities before the spring's look-up: then no
            // particle index (nor its three-fold) is held across that look-up, which took them
            // to the stack and back (the fill 70.4 → 65.7 instructions per particle-step of the
            // 19.2k LIGGGHTS bed, sixty-third round).
            pairs.set(
                lane,
                LanePair {
                    owner,
                    partner,
                    slot: p,
                },
            );
            lanes.set_pair(
                lane,
                separation,
                [r_a, r_b],
                [reads.mass.get(owner), reads.mass.get(partner)],
                reads.velocity.get(owner) - reads.velocity.get(partner),
            );
            // With one material the lanes hold its parameters already: then none is loaded.
            if !uniform {
                let material = PairMaterial::of(
                    model,
                    reads.material.get(owner),
                    reads.material.get(partner),
                );
                lanes.set_pair_material::<BONDS, FRICTION>(lane, &material);
            }
            if BONDS {
                let state = states.map_or(BondState::Unbonded, |states| states.read(p));
                let melted = melted.map_or((false, false), |melted| {
                    (melted.get(owner), melted.get(partner))
                });
                let criterion = model.bond_criterion.holds(melted.0, melted.1);
                lanes.set_bond(lane, state, criterion);
            }
            // With friction the particles rotate: the pass has their angular velocities (checked
            // above), and no zero stand-ins are made for a case that cannot arise.
            if let Some(omega) = omega {
                lanes.set_angular_velocity(lane, [omega.get(owner), omega.get(partner)]);
                let held = springs.read(p, |slot, spring| {
                    release(slab, &targets.lost, slot, spring);
                });
                lanes.set_held(lane, held);
            }
            filled = lane + 1;
            if filled == LANES {
                let full = (&mut *lanes, &*pairs, LANES, &mut *springs);
                write_lanes::<BONDS, FRICTION, HEAT>(
                    model, reads, targets, full, interval, set, summary,
                );
                filled = 0;
            }
        }
        filled
    });
    batch.kept.0.clear();
}

/// Asks for the partners' lines the fill and the write-back of `kept` will read and write,
/// ahead of them: velocity and mass, force and lost energy, with `FRICTION` spin and torque,
/// and with `HEAT` temperature and heat sums. The sift read the partners' positions and radii;
/// these lines it did not. With every datum in the cache a prefetch costs an instruction; on a
/// bed larger than the cache a partner's lines are otherwise missed one contact after the other
/// (docs/performance-log.md, thirty-fourth round). The lost energy and the torque, which the
/// write-back adds to, were left out at first: asking for them too made the 97.2k bed 1.07
/// times faster again at 1 thread on a Zen 3 host (1.045 with heat; thirty-fifth round). The
/// temperature and heat sums gained nothing there. On a Zen 4 host, where 37 % of the heated
/// write-back's samples waited on them, they made the heated 97.2k bed 1.042 times faster by
/// paired runs (two processes sharing the third-level cache), about 1.0 alone (fifty-second
/// round).
#[inline(always)]
fn prefetch_partner<'s, const FRICTION: bool, const HEAT: bool>(
    reads: ParticleReads<'_, 's>,
    targets: &OpenTargets<'_, 's>,
    partner: Member<'s>,
) {
    reads.velocity.prefetch(partner);
    reads.mass.prefetch(partner);
    targets.force.prefetch(partner);
    targets.lost.prefetch(partner);
    if FRICTION {
        if let Some(omega) = reads.angular_velocity {
            omega.prefetch(partner);
        }
        if let Some(torque) = &targets.torque {
            torque.prefetch(partner);
        }
    }
    if HEAT {
        if let Some(heat) = &targets.heat {
            heat.temperature.prefetch(partner);
            heat.sums.prefetch(partner);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The batch buffers' reuse rests on `recycle` keeping the allocation: a change of the
    /// standard library that lost it would cost an allocation per slab visit, which this test
    /// would show.
    #[test]
    fn recycling_an_empty_buffer_keeps_its_allocation() {
        let mut numbers: Vec<u64> = Vec::with_capacity(100);
        numbers.extend(0..50);
        let address = numbers.as_ptr() as usize;
        let floats: Vec<f64> = recycle(numbers);
        assert!(floats.is_empty());
        assert!(floats.capacity() >= 100, "capacity {}", floats.capacity());
        assert_eq!(floats.as_ptr() as usize, address);
    }
}
