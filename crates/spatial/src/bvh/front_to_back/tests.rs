//! Tests of the front-to-back walks: order, seeds, whole subtrees, items and nodes passed over.

use sightline_scene::{Angle, Camera, LookAt};

use super::*;
use crate::bvh::traverse::tests::{grid_boxes, random_boxes};
use crate::{BvhPreset, Containment};

/// The seeds answer "yes" for exactly their slots, whatever the filter's bits share:
/// 200 seeds (a filter a fifth full) against every slot up to 300,000 and the largest.
#[test]
fn seeds_contain_exactly_their_slots() {
    let slots: std::collections::HashSet<u32> = (0..200u32).map(|i| i * 1_499 + 7).chain([0, u32::MAX]).collect();
    let seeds = Seeds::new(slots.iter().copied());
    let mut false_positive_bits = 0;
    for s in (0..300_000u32).chain([u32::MAX - 1, u32::MAX]) {
        assert_eq!(seeds.contains(s), slots.contains(&s), "slot {s}");
        let b = Seeds::bit(s);
        false_positive_bits += (seeds.filter[b / 64] >> (b % 64) & 1 != 0 && !slots.contains(&s)) as u32;
    }
    assert!(false_positive_bits > 0, "the filter alone is not exact here: the search decides");
    assert!(!Seeds::default().contains(0));
}

/// An eye over `random_boxes`' field and its frustum, looking at the field from a random
/// height with a random field of view; case `c` picks the far distance (10, 60 or 400).
fn random_view(rng: &mut sightline_scene::rng::Rng, c: usize) -> (Vec3, Frustum) {
    let eye = Vec3::new(rng.range(-70.0, 70.0), rng.range(-5.0, 10.0), rng.range(-70.0, 70.0));
    let look = LookAt {
        eye,
        target: Vec3::new(rng.range(-30.0, 30.0), 0.0, rng.range(-30.0, 30.0)),
        up: Vec3::Y,
        fovy: Angle::degrees(rng.range(20.0, 100.0)),
        near: 0.1,
        far: [10.0, 60.0, 400.0][c % 3],
    };
    (eye, Frustum::from_camera(&Camera::perspective(&look, 1.5).unwrap()))
}

#[test]
fn front_to_back_is_roughly_sorted_and_callbacks_prune() {
    let boxes = grid_boxes();
    let bvh = Bvh::build(&boxes, BvhPreset::Fast, 4);
    let eye = Vec3::new(-40.0, 0.5, -40.0);
    let mut order = Vec::new();
    bvh.order_front_to_back(eye, &mut order);
    assert_eq!(order.len(), boxes.len());
    let d = |i: u32| boxes[i as usize].distance_squared(eye).sqrt();
    // The first item is the nearest; the first tenth is nearer than the last tenth.
    assert_eq!(order[0], 0);
    let head: f32 = order[..40].iter().map(|&i| d(i)).sum::<f32>() / 40.0;
    let tail: f32 = order[360..].iter().map(|&i| d(i)).sum::<f32>() / 40.0;
    assert!(head * 1.5 < tail, "{head} {tail}");
    // A callback that rejects everything beyond x > 0 never sees items there.
    let mut got = Vec::new();
    bvh.traverse_front_to_back(
        None,
        eye,
        |b| if b.min.x > 0.0 { Visit::Skip } else { Visit::Continue },
        |v| {
            got.push(v.index);
            Visit::Continue
        },
    );
    assert!(got.iter().all(|&i| boxes[i as usize].min.x <= 0.0));
    assert_eq!(got.len(), 220);
}

/// A cursor that puts the k nearest items first emits them first, nearest first (the k
/// smallest box distances among the items in the frustum), then the rest: every item
/// the plain walk emits, once, with the same `inside` flags; unbounded items still lead.
#[test]
fn nearest_first_leads_with_the_nearest_and_keeps_the_set() {
    let mut rng = sightline_scene::rng::Rng::new(5);
    let mut boxes = random_boxes(&mut rng);
    boxes[11] = Aabb::new(Vec3::splat(f32::NEG_INFINITY), Vec3::splat(f32::INFINITY));
    let mut led = 0;
    for leaf in [1, 4, 8] {
        let bvh = Bvh::build(&boxes, BvhPreset::Fast, leaf);
        for c in 0..30 {
            let (eye, frustum) = random_view(&mut rng, c);
            let f = (c % 4 != 0).then_some(&frustum);
            let walk = |k: usize| {
                let mut cursor = FrontToBackCursor::new(&bvh, f, eye).nearest_first(&bvh, k);
                let mut out = Vec::new();
                while cursor.next_batch(&bvh, |_| true, 5, &mut out) {}
                assert!(cursor.is_done());
                out
            };
            let plain = walk(0);
            // Seeding a walk under way, or twice, changes nothing.
            let mut late = FrontToBackCursor::new(&bvh, f, eye);
            let mut out = Vec::new();
            late.next_batch(&bvh, |_| true, 3, &mut out);
            late = late.nearest_first(&bvh, 10).nearest_first(&bvh, 10);
            while late.next_batch(&bvh, |_| true, 5, &mut out) {}
            assert_eq!(
                out.iter().map(|v| v.index).collect::<Vec<_>>(),
                plain.iter().map(|v| v.index).collect::<Vec<_>>()
            );
            let k = [1, 7, 32, 5000][c % 4];
            let seeded = walk(k);
            let sorted = |v: &[Visible]| {
                let mut v: Vec<(u32, bool)> = v.iter().map(|v| (v.index, v.inside)).collect();
                v.sort_unstable();
                v
            };
            assert_eq!(sorted(&seeded), sorted(&plain), "leaf {leaf}, camera {c}, k {k}");
            // The unbounded item, then the k nearest by box distance.
            assert_eq!(seeded[0].index, 11);
            let d = |i: u32| boxes[i as usize].distance_squared(eye);
            let mut dist: Vec<f32> = plain.iter().filter(|v| v.index != 11).map(|v| d(v.index)).collect();
            dist.sort_unstable_by(f32::total_cmp);
            let head: Vec<f32> = seeded[1..].iter().take(k).map(|v| d(v.index)).collect();
            assert_eq!(head, dist[..head.len()], "leaf {leaf}, camera {c}, k {k}");
            assert_eq!(head.len(), k.min(dist.len()));
            led += head.len();
        }
    }
    assert!(led > 1000, "{led} items led");
}

/// Whole subtrees change the order only: every item the plain walk emits comes once,
/// with the same `inside` flag, for any batch size (each batch but the last full), with
/// or without seeds and a frustum. With 0 the order is the plain one; sizes saturate
/// (255 is "255 or more", never taken whole, however large the limit asked for).
#[test]
fn whole_subtrees_change_the_order_only() {
    let mut rng = sightline_scene::rng::Rng::new(9);
    let boxes = random_boxes(&mut rng);
    let mut reordered = 0;
    for leaf in [1, 4] {
        let bvh = Bvh::build(&boxes, BvhPreset::Fast, leaf);
        // Each node's size is its subtree's item count, saturated (checked by
        // `validate`); the root's 3,000 items saturate.
        bvh.validate().unwrap();
        assert_eq!(bvh.sizes[0], 255);
        for c in 0..16 {
            let (eye, frustum) = random_view(&mut rng, c);
            let f = (c % 4 != 0).then_some(&frustum);
            let walk = |whole: u32, k: usize, batch: usize| {
                let mut cursor = FrontToBackCursor::new(&bvh, f, eye).nearest_first(&bvh, k).whole_subtrees(whole);
                let mut out = Vec::new();
                loop {
                    let before = out.len();
                    let more = cursor.next_batch(&bvh, |_| true, batch, &mut out);
                    if !more {
                        break;
                    }
                    assert_eq!(out.len() - before, batch, "whole {whole}, k {k}");
                }
                out
            };
            let sorted = |v: &[Visible]| {
                let mut v: Vec<(u32, bool)> = v.iter().map(|v| (v.index, v.inside)).collect();
                v.sort_unstable();
                v
            };
            let ids = |v: &[Visible]| v.iter().map(|v| v.index).collect::<Vec<_>>();
            let plain = walk(0, 0, usize::MAX);
            for whole in [0, 1, 3, 16, 254, 255, 100_000] {
                for (k, batch) in [(0, 1), (7, 5), (32, 64), (0, usize::MAX)] {
                    let got = walk(whole, k, batch);
                    assert_eq!(sorted(&got), sorted(&plain), "leaf {leaf}, camera {c}, whole {whole}, k {k}");
                    if whole == 0 && k == 0 {
                        assert_eq!(ids(&got), ids(&plain));
                    }
                    reordered += (k == 0 && ids(&got) != ids(&plain)) as u32;
                }
            }
        }
    }
    assert!(reordered > 20, "{reordered} walks reordered");
}

/// Runs `cursor` to its end in batches of `batch`, every box possibly visible, passing over
/// what `over` and `known` say: the items emitted (index, inside) and the boxes asked about.
fn walk_except(
    mut cursor: FrontToBackCursor,
    bvh: &Bvh,
    over: impl Fn(u32) -> bool,
    known: &NodeSet,
    batch: usize,
) -> (Vec<(u32, bool)>, usize) {
    let (mut out, mut asked) = (Vec::new(), 0);
    let mut ask = |_: &Aabb| {
        asked += 1;
        true
    };
    while cursor.next_batch_except(bvh, &mut ask, &over, known, batch, &mut out) {}
    (out.iter().map(|v| (v.index, v.inside)).collect(), asked)
}

/// Items passed over are neither asked about nor emitted, and the rest come in the plain
/// walk's order: with and without a frustum, seeds, whole subtrees and an unbounded item
/// (passed over or not), for any batch size. Every callback the plain walk makes for a
/// passed-over item is saved (here every box is possibly visible, so the plain walk asks
/// about exactly the items it emits, once each).
#[test]
fn items_passed_over_are_neither_asked_about_nor_emitted() {
    let mut rng = sightline_scene::rng::Rng::new(13);
    let mut boxes = random_boxes(&mut rng);
    boxes[11] = Aabb::new(Vec3::splat(f32::NEG_INFINITY), Vec3::splat(f32::INFINITY));
    let mut saved = 0;
    for leaf in [1, 4] {
        let bvh = Bvh::build(&boxes, BvhPreset::Fast, leaf);
        for c in 0..16 {
            let (eye, frustum) = random_view(&mut rng, c);
            let f = (c % 4 != 0).then_some(&frustum);
            let (k, whole, batch) = [(0, 0, 1), (7, 0, 5), (0, 16, 64), (32, 16, usize::MAX)][c % 4];
            let modulus = [2, 3, 5][c % 3];
            let over = |i: u32| i % modulus == c as u32 % modulus;
            let walk = |except: bool| {
                let cursor = FrontToBackCursor::new(&bvh, f, eye).nearest_first(&bvh, k).whole_subtrees(whole);
                walk_except(cursor, &bvh, |i| except && over(i), &NodeSet::default(), batch)
            };
            let (plain, plain_asked) = walk(false);
            let (got, asked) = walk(true);
            let kept: Vec<(u32, bool)> = plain.iter().copied().filter(|&(i, _)| !over(i)).collect();
            assert_eq!(got, kept, "leaf {leaf}, camera {c}");
            assert!(kept.len() < plain.len(), "leaf {leaf}, camera {c}: nothing passed over");
            let passed = plain.len() - kept.len();
            if whole == 0 {
                assert_eq!(plain_asked - asked, passed, "leaf {leaf}, camera {c}");
            }
            saved += passed;
        }
    }
    assert!(saved > 1000, "{saved} items passed over");
}

/// `nodes_holding` holds exactly the nodes with an item of the set in their subtree. A
/// walk given them asks about none it reaches and emits what it emits without them (here
/// every box is possibly visible): each node of the set that the walk reaches (its box
/// not outside the frustum) saves one question, except one-item leaves, whose item is
/// passed over before anything is asked.
#[test]
fn nodes_holding_passed_over_items_are_not_asked_about() {
    let mut rng = sightline_scene::rng::Rng::new(17);
    let boxes = random_boxes(&mut rng);
    let mut saved = 0;
    for leaf in [1, 4] {
        let bvh = Bvh::build(&boxes, BvhPreset::Fast, leaf);
        fn items(bvh: &Bvh, k: usize, out: &mut Vec<u32>) {
            let n = bvh.nodes[k];
            if n.is_leaf() {
                out.extend(&bvh.items[n.index as usize..(n.index + n.count) as usize]);
            } else {
                items(bvh, n.index as usize, out);
                items(bvh, n.index as usize + 1, out);
            }
        }
        for c in 0..12 {
            let (eye, frustum) = random_view(&mut rng, c);
            let f = (c % 3 != 0).then_some(&frustum);
            let modulus = [7, 40, 400][c % 3];
            let over = |i: u32| i % modulus == 1;
            let mut known = NodeSet::default();
            bvh.nodes_holding(over, &mut known);
            let mut expected = 0;
            for k in 0..bvh.nodes.len() {
                let mut under = Vec::new();
                items(&bvh, k, &mut under);
                let holds = under.iter().any(|&i| over(i));
                assert_eq!(known.contains(k as u32), holds, "leaf {leaf}, camera {c}, node {k}");
                let outside = f.is_some_and(|f| f.classify(&bvh.nodes[k].aabb()) == Containment::Outside);
                expected += (holds && bvh.nodes[k].count != 1 && !outside) as usize;
            }
            let walk = |known: &NodeSet| walk_except(FrontToBackCursor::new(&bvh, f, eye), &bvh, over, known, 16);
            let (plain, plain_asked) = walk(&NodeSet::default());
            let (got, asked) = walk(&known);
            assert_eq!(got, plain, "leaf {leaf}, camera {c}");
            assert_eq!(plain_asked - asked, expected, "leaf {leaf}, camera {c}");
            saved += expected;
        }
    }
    assert!(saved > 500, "{saved} questions saved");
}

/// A node or item box's answer in the parallel walk's tests: a hash of its corners and of
/// `salt`, so that about one box in `one_in` is "hidden".
fn hidden(b: &Aabb, salt: u32, one_in: u32) -> bool {
    let bits = [b.min.x, b.min.z, b.max.y]
        .iter()
        .fold(salt.wrapping_mul(0x9E37_79B9), |h, v| (h ^ v.to_bits()).wrapping_mul(0x85EB_CA6B).rotate_left(13));
    bits % one_in == 0
}

/// The parallel batches: with answers that do not change, every batch together are the
/// serial walk's items in its order, asked the same number of questions (the dropped walks'
/// are not counted); each batch but the last holds at least the batch size and fewer than
/// twice as many; and the batches, and the questions counted in each, are the same on one,
/// two and three threads. Trees of one, four and 100 items a leaf (leaves split into their
/// items), with and without a frustum, seeds, items passed over and nodes not asked about.
#[test]
fn parallel_batches_keep_the_serial_order_on_any_thread_count() {
    let mut rng = sightline_scene::rng::Rng::new(17);
    let boxes = random_boxes(&mut rng);
    let pools: Vec<rayon::ThreadPool> =
        [1, 2, 3].iter().map(|&t| rayon::ThreadPoolBuilder::new().num_threads(t).build().unwrap()).collect();
    let mut batches_seen = 0;
    for (case, leaf) in [1, 4, 100].into_iter().cycle().take(12).enumerate() {
        let bvh = Bvh::build(&boxes, BvhPreset::Fast, leaf);
        let (eye, frustum) = random_view(&mut rng, case);
        let f = (case % 4 != 3).then_some(&frustum);
        let seeds = [0, 32][case % 2];
        let max = [1, 7, 64, 300][case % 4];
        let passed_over = |i: u32| case % 3 != 0 && i.is_multiple_of(5);
        let mut known = NodeSet::default();
        if case % 3 == 2 {
            bvh.nodes_holding(passed_over, &mut known);
        }
        let cursor = || FrontToBackCursor::new(&bvh, f, eye).nearest_first(&bvh, seeds);
        let (mut serial, mut asked) = (Vec::new(), 0u64);
        let mut c = cursor();
        while c.next_batch_except(&bvh, |b| (asked += 1, !hidden(b, 0, 3)).1, passed_over, &known, max, &mut serial) {}
        let mut runs = Vec::new();
        for pool in &pools {
            let (mut c, mut batches) = (cursor(), Vec::new());
            pool.install(|| loop {
                let (mut out, mut states) = (Vec::new(), Vec::new());
                let tests = (|| 0u64, |n: &mut u64, b: &Aabb| (*n += 1, !hidden(b, 0, 3)).1);
                let more = c.next_batch_parallel(&bvh, tests, (passed_over, &known), max, &mut out, &mut states);
                batches.push((out, states.iter().sum::<u64>()));
                if !more {
                    break;
                }
            });
            runs.push(batches);
        }
        let at = format!("case {case}, leaf {leaf}, batch {max}");
        for batches in &runs {
            let all: Vec<Visible> = batches.iter().flat_map(|b| b.0.iter().copied()).collect();
            assert_eq!(all.len(), serial.len(), "{at}");
            assert!(all.iter().zip(&serial).all(|(a, b)| a.index == b.index && a.inside == b.inside), "{at}");
            assert_eq!(batches.iter().map(|b| b.1).sum::<u64>(), asked, "{at}: questions counted");
            let (last, full) = batches.split_last().unwrap();
            assert!(full.iter().all(|b| b.0.len() >= max && b.0.len() < 2 * max), "{at}");
            assert!(last.0.len() < 2 * max, "{at}");
        }
        let same = |a: &Vec<(Vec<Visible>, u64)>, b: &Vec<(Vec<Visible>, u64)>| {
            a.len() == b.len()
                && a.iter()
                    .zip(b)
                    .all(|(x, y)| x.1 == y.1 && x.0.iter().map(|v| v.index).eq(y.0.iter().map(|v| v.index)))
        };
        assert!(same(&runs[0], &runs[1]) && same(&runs[0], &runs[2]), "{at}: batches depend on the thread count");
        batches_seen += runs[0].len();
    }
    assert!(batches_seen > 100, "{batches_seen} batches");
}

/// With answers that change after every batch (as a depth pyramid fills), the parallel
/// batches are still the same on one, two and three threads, no item comes twice, and
/// none passed over comes at all.
#[test]
fn parallel_batches_with_changing_answers_are_the_same_on_any_thread_count() {
    let mut rng = sightline_scene::rng::Rng::new(23);
    let boxes = random_boxes(&mut rng);
    let bvh = Bvh::build(&boxes, BvhPreset::Fast, 4);
    let mut runs = Vec::new();
    for threads in [1, 2, 3] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let mut batches = Vec::new();
        for case in 0..6 {
            let (eye, frustum) = random_view(&mut sightline_scene::rng::Rng::new(100 + case as u64), case);
            let mut c = FrontToBackCursor::new(&bvh, (case % 3 != 2).then_some(&frustum), eye);
            let (mut salt, mut items) = (1 + 1000 * case as u32, Vec::new());
            pool.install(|| loop {
                let (mut out, mut states) = (Vec::new(), Vec::new());
                let tests = (|| 0u64, |n: &mut u64, b: &Aabb| (*n += 1, !hidden(b, salt, 12)).1);
                let except = (|i| i % 7 == 0, &NodeSet::default());
                let more = c.next_batch_parallel(&bvh, tests, except, 16, &mut out, &mut states);
                items.extend(out.iter().map(|v| v.index));
                batches.push((out.iter().map(|v| v.index).collect::<Vec<_>>(), states.iter().sum::<u64>()));
                salt += 1;
                if !more {
                    break;
                }
            });
            assert!(items.iter().all(|i| i % 7 != 0), "an item passed over came");
            let mut unique = items.clone();
            unique.sort_unstable();
            unique.dedup();
            assert_eq!(unique.len(), items.len(), "an item came twice");
        }
        let items = batches.iter().map(|b| b.0.len()).sum::<usize>();
        assert!(batches.len() > 30 && items > 500, "{} batches, {items} items", batches.len());
        runs.push(batches);
    }
    assert_eq!(runs[0], runs[1]);
    assert_eq!(runs[0], runs[2]);
}
