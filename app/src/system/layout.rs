//! Layered (Sugiyama-style) layout of a graph drawn left to right: cycles broken by reversing
//! the edges a depth-first search finds going back, layers by longest path from the sources,
//! crossings reduced by barycentre sweeps, then columns and rows packed from the boxes' sizes.
//! A long chain of layers is folded into bands, one under the other, each about as wide, so that
//! the whole opens on a screen at a zoom where names read rather than as a strip cut off at both
//! ends. Pure: no egui, no diagram; `Diagram::arrange` feeds it blocks and links.
//!
//! Written here rather than taken from crates.io: `layout-rs` lays out for its own SVG/DOT
//! output with its own node shapes (no per-node sizes in, positions out), and `rust-sugiyama`
//! works on point-sized vertices; both would need converting to and from, for about the size of
//! this file.

/// Gap between columns (where the wires run) and between boxes of one column, in canvas units.
pub const COLUMN_GAP: f32 = 90.0;
pub const ROW_GAP: f32 = 36.0;
/// The widest a band of columns is made before the next columns go into a band below: what a
/// 1280-point window's canvas shows at the fit's floor (`viewer::FIT_FLOOR`), with a margin.
pub const FOLD_WIDTH: f32 = 1500.0;
/// Between bands, where the wires from one band's end to the next one's start run back.
pub const BAND_GAP: f32 = 110.0;
/// Barycentre sweeps (each one down and back up): a few are enough on systems this size.
const SWEEPS: usize = 6;

/// Top-left corners for boxes of `sizes` (`[width, height]`), with `edges` (from, to) between
/// indices into `sizes`, laid out left to right from `origin`, in bands of at most
/// [`FOLD_WIDTH`]. Edges to unknown indices and self-loops are ignored.
pub fn layered(sizes: &[[f32; 2]], edges: &[(usize, usize)], origin: [f32; 2]) -> Vec<[f32; 2]> {
    layered_within(sizes, edges, origin, FOLD_WIDTH)
}

/// [`layered`] with bands at most `fold_width` wide (one column at least; infinite: one band).
pub fn layered_within(
    sizes: &[[f32; 2]],
    edges: &[(usize, usize)],
    origin: [f32; 2],
    fold_width: f32,
) -> Vec<[f32; 2]> {
    let count = sizes.len();
    let edges: Vec<(usize, usize)> = edges
        .iter()
        .copied()
        .filter(|&(from, to)| from != to && from < count && to < count)
        .collect();
    let edges = acyclic(count, &edges);
    let layers = longest_path_layers(count, &edges);
    let order = reduce_crossings(count, &edges, &layers);
    place(sizes, &order, origin, fold_width)
}

/// The edges with those that close a cycle reversed (found going back in a depth-first search
/// from each node in turn, so the input order decides which edge of a cycle turns).
pub fn acyclic(count: usize, edges: &[(usize, usize)]) -> Vec<(usize, usize)> {
    let mut out: Vec<Vec<usize>> = vec![Vec::new(); count];
    for (index, &(from, _)) in edges.iter().enumerate() {
        out[from].push(index);
    }
    // 0 unvisited, 1 on the stack, 2 done.
    let mut state = vec![0u8; count];
    let mut reversed = vec![false; edges.len()];
    for root in 0..count {
        if state[root] != 0 {
            continue;
        }
        // An explicit stack: a deep chain must not overflow the thread's stack.
        let mut stack = vec![(root, 0usize)];
        state[root] = 1;
        while let Some((node, next)) = stack.last_mut() {
            let node = *node;
            if let Some(&edge) = out[node].get(*next) {
                *next += 1;
                let to = edges[edge].1;
                match state[to] {
                    0 => {
                        state[to] = 1;
                        stack.push((to, 0));
                    }
                    1 => reversed[edge] = true,
                    _ => {}
                }
            } else {
                state[node] = 2;
                stack.pop();
            }
        }
    }
    edges
        .iter()
        .zip(reversed)
        .map(|(&(from, to), reversed)| if reversed { (to, from) } else { (from, to) })
        .collect()
}

/// Each node's layer: 0 for sources, else one more than its furthest predecessor's. `edges`
/// must be acyclic.
fn longest_path_layers(count: usize, edges: &[(usize, usize)]) -> Vec<usize> {
    let mut indegree = vec![0usize; count];
    let mut out: Vec<Vec<usize>> = vec![Vec::new(); count];
    for &(from, to) in edges {
        indegree[to] += 1;
        out[from].push(to);
    }
    let mut layer = vec![0usize; count];
    let mut ready: Vec<usize> = (0..count).filter(|&node| indegree[node] == 0).collect();
    while let Some(node) = ready.pop() {
        for &to in &out[node] {
            layer[to] = layer[to].max(layer[node] + 1);
            indegree[to] -= 1;
            if indegree[to] == 0 {
                ready.push(to);
            }
        }
    }
    layer
}

/// The nodes of each layer, top to bottom. Long edges are followed through virtual nodes, one
/// per layer crossed, so that they pull on the order like short ones; the virtual nodes are
/// dropped from what is returned.
fn reduce_crossings(count: usize, edges: &[(usize, usize)], layers: &[usize]) -> Vec<Vec<usize>> {
    let depth = layers.iter().max().map_or(0, |max| max + 1);
    let mut layer_of = layers.to_vec();
    let mut segments: Vec<(usize, usize)> = Vec::new();
    for &(from, to) in edges {
        let mut previous = from;
        for layer in layers[from] + 1..layers[to] {
            let virtual_node = layer_of.len();
            layer_of.push(layer);
            segments.push((previous, virtual_node));
            previous = virtual_node;
        }
        segments.push((previous, to));
    }
    let total = layer_of.len();
    let mut up: Vec<Vec<usize>> = vec![Vec::new(); total];
    let mut down: Vec<Vec<usize>> = vec![Vec::new(); total];
    for &(from, to) in &segments {
        down[from].push(to);
        up[to].push(from);
    }
    let mut order: Vec<Vec<usize>> = vec![Vec::new(); depth];
    for node in 0..total {
        order[layer_of[node]].push(node);
    }
    let mut rank = vec![0f32; total];
    let set_ranks = |order: &[Vec<usize>], rank: &mut [f32]| {
        for layer in order {
            for (index, &node) in layer.iter().enumerate() {
                rank[node] = index as f32;
            }
        }
    };
    set_ranks(&order, &mut rank);
    let mut best = order.clone();
    let mut best_crossings = crossings(&order, &down, &rank);
    for _ in 0..SWEEPS {
        for layer in order.iter_mut().skip(1) {
            sort_by_barycentre(layer, &up, &mut rank);
        }
        for layer in order.iter_mut().rev().skip(1) {
            sort_by_barycentre(layer, &down, &mut rank);
        }
        let now = crossings(&order, &down, &rank);
        if now < best_crossings {
            best_crossings = now;
            best.clone_from(&order);
        }
    }
    for layer in &mut best {
        layer.retain(|&node| node < count);
    }
    best
}

/// Sorts one layer by the mean rank of each node's neighbours in `neighbours` (a node without
/// any keeps its place), then renumbers the layer's ranks.
fn sort_by_barycentre(layer: &mut [usize], neighbours: &[Vec<usize>], rank: &mut [f32]) {
    let mut keyed: Vec<(f32, usize)> = layer
        .iter()
        .map(|&node| {
            let around = &neighbours[node];
            let key = if around.is_empty() {
                rank[node]
            } else {
                around.iter().map(|&other| rank[other]).sum::<f32>() / around.len() as f32
            };
            (key, node)
        })
        .collect();
    keyed.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (index, (_, node)) in keyed.into_iter().enumerate() {
        layer[index] = node;
        rank[node] = index as f32;
    }
}

/// Crossings between consecutive layers (each segment spans one layer).
fn crossings(order: &[Vec<usize>], down: &[Vec<usize>], rank: &[f32]) -> usize {
    let mut total = 0;
    for layer in order {
        let mut pairs: Vec<(f32, f32)> = Vec::new();
        for &node in layer {
            for &to in &down[node] {
                pairs.push((rank[node], rank[to]));
            }
        }
        for (index, a) in pairs.iter().enumerate() {
            for b in &pairs[index + 1..] {
                if (a.0 - b.0) * (a.1 - b.1) < 0.0 {
                    total += 1;
                }
            }
        }
    }
    total
}

/// Columns as wide as their widest box, boxes stacked in each column, the columns centred on one
/// another vertically within their band; the bands (runs of consecutive columns, as many as
/// `fold_width` asks for and about equally wide) one under the other.
fn place(
    sizes: &[[f32; 2]],
    order: &[Vec<usize>],
    origin: [f32; 2],
    fold_width: f32,
) -> Vec<[f32; 2]> {
    let mut positions = vec![origin; sizes.len()];
    let heights: Vec<f32> = order
        .iter()
        .map(|layer| {
            let boxes: f32 = layer.iter().map(|&node| sizes[node][1]).sum();
            boxes + ROW_GAP * layer.len().saturating_sub(1) as f32
        })
        .collect();
    let widths: Vec<f32> = order
        .iter()
        .map(|layer| layer.iter().map(|&node| sizes[node][0]).fold(0.0, f32::max))
        .collect();
    let mut y_band = origin[1];
    for band in bands(&widths, fold_width) {
        let tallest = heights[band.clone()].iter().copied().fold(0.0, f32::max);
        let mut x = origin[0];
        for column in band {
            let mut y = y_band + (tallest - heights[column]) / 2.0;
            for &node in &order[column] {
                positions[node] = [x, y];
                y += sizes[node][1] + ROW_GAP;
            }
            x += widths[column] + COLUMN_GAP;
        }
        y_band += tallest + BAND_GAP;
    }
    positions
}

/// Consecutive runs of columns of `widths`: as few as keep each within `fold_width` when
/// packed, and the breaks placed so that the bands come out about equally wide.
fn bands(widths: &[f32], fold_width: f32) -> Vec<std::ops::Range<usize>> {
    let span = |columns: &[f32]| {
        columns.iter().sum::<f32>() + COLUMN_GAP * columns.len().saturating_sub(1) as f32
    };
    let total = span(widths);
    if widths.is_empty() || total <= fold_width {
        return std::iter::once(0..widths.len()).collect();
    }
    // Each column goes to the band its middle falls in when the unfolded width is cut in
    // `count` equal parts; the fewest parts whose bands all fit.
    let mut middles = Vec::with_capacity(widths.len());
    let mut x = 0.0;
    for width in widths {
        middles.push(x + width / 2.0);
        x += width + COLUMN_GAP;
    }
    let mut count = (total / fold_width).ceil() as usize;
    loop {
        let mut found: Vec<std::ops::Range<usize>> = Vec::new();
        for (column, middle) in middles.iter().enumerate() {
            let band = ((middle / total * count as f32) as usize).min(count - 1);
            if found.len() > band {
                if let Some(last) = found.last_mut() {
                    last.end = column + 1;
                }
            } else {
                found.push(column..column + 1);
            }
        }
        let fits = found
            .iter()
            .all(|band| band.len() == 1 || span(&widths[band.clone()]) <= fold_width);
        if fits || count >= widths.len() {
            return found;
        }
        count += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator, so that the test needs no crate and fails the same way
    /// every time.
    fn next(seed: &mut u64) -> u64 {
        *seed ^= *seed << 13;
        *seed ^= *seed >> 7;
        *seed ^= *seed << 17;
        *seed
    }

    #[test]
    fn random_dag_has_no_overlaps_and_every_edge_goes_right() {
        let mut seed = 0x9e37_79b9_7f4a_7c15;
        let count = 60;
        let sizes: Vec<[f32; 2]> = (0..count)
            .map(|_| {
                [
                    120.0 + (next(&mut seed) % 120) as f32,
                    60.0 + (next(&mut seed) % 100) as f32,
                ]
            })
            .collect();
        let mut edges = Vec::new();
        for _ in 0..100 {
            let a = (next(&mut seed) % count as u64) as usize;
            let b = (next(&mut seed) % count as u64) as usize;
            if a < b {
                edges.push((a, b));
            }
        }
        // One cycle: its back edge is the only one allowed to go right to left.
        edges.push((count - 1, 0));
        let acyclic_edges = acyclic(count, &edges);
        let positions = layered_within(&sizes, &edges, [40.0, 40.0], f32::INFINITY);
        for i in 0..count {
            for j in i + 1..count {
                let (a, b) = (positions[i], positions[j]);
                let apart = a[0] + sizes[i][0] <= b[0]
                    || b[0] + sizes[j][0] <= a[0]
                    || a[1] + sizes[i][1] <= b[1]
                    || b[1] + sizes[j][1] <= a[1];
                assert!(apart, "blocks {i} and {j} overlap: {a:?} {b:?}");
            }
        }
        let mut reversed = 0;
        for (&(from, to), &(left, right)) in edges.iter().zip(&acyclic_edges) {
            assert!(
                positions[left][0] + sizes[left][0] < positions[right][0],
                "edge {from}->{to} does not go left to right"
            );
            if (left, right) != (from, to) {
                reversed += 1;
            }
        }
        assert!(reversed <= 1, "only the cycle's back edge may be reversed");
    }

    #[test]
    fn barycentre_untangles_a_crossed_pair() {
        // 0->3 and 1->2: laid out as given, these two cross.
        let sizes = [[100.0, 50.0]; 4];
        let positions = layered(&sizes, &[(0, 3), (1, 2)], [0.0, 0.0]);
        let goes_down = positions[0][1] < positions[1][1];
        assert_eq!(goes_down, positions[3][1] < positions[2][1]);
    }

    #[test]
    fn a_long_chain_is_folded_into_bands_that_fit_without_overlaps() {
        // A chain of twelve blocks, as a robot's loop through sensors, behaviours and motors.
        let sizes: Vec<[f32; 2]> = (0..12)
            .map(|i| [180.0 + 20.0 * (i % 3) as f32, 60.0 + 15.0 * (i % 4) as f32])
            .collect();
        let edges: Vec<(usize, usize)> = (0..11).map(|i| (i, i + 1)).collect();
        let positions = layered(&sizes, &edges, [0.0, 0.0]);
        let right = |i: usize| positions[i][0] + sizes[i][0];
        let bottom = |i: usize| positions[i][1] + sizes[i][1];
        let width = (0..12).map(right).fold(0.0, f32::max);
        assert!(width <= FOLD_WIDTH, "{width} wide");
        let height = (0..12).map(bottom).fold(0.0, f32::max);
        assert!(width / height < 4.0, "{width} × {height}: still a strip");
        let mut bands = 1;
        for (from, to) in edges {
            if positions[to][0] > right(from) {
                continue;
            }
            // A fold: the chain goes on at the left of the band below.
            bands += 1;
            assert!(positions[to][1] > bottom(from), "{to} under {from}");
        }
        assert!(bands >= 2, "folded");
        for i in 0..12 {
            for j in i + 1..12 {
                let apart = right(i) <= positions[j][0]
                    || right(j) <= positions[i][0]
                    || bottom(i) <= positions[j][1]
                    || bottom(j) <= positions[i][1];
                assert!(apart, "blocks {i} and {j} overlap");
            }
        }
    }

    #[test]
    fn bands_are_about_equal_and_within_the_width() {
        let widths = [200.0; 10];
        let found = bands(&widths, 1000.0);
        // 10 columns of 200 with gaps of 90: 2810 wide, and at most 3 columns fit in 1000: four
        // bands of 2 or 3 columns.
        assert_eq!(found.len(), 4, "{found:?}");
        assert!(
            found.iter().all(|band| (2..=3).contains(&band.len())),
            "{found:?}"
        );
        assert_eq!(
            bands(&widths, f32::INFINITY).len(),
            1,
            "one band when it fits"
        );
        assert_eq!(
            bands(&[5000.0, 5000.0], 1000.0),
            [0..1, 1..2],
            "a column wider alone"
        );
    }
}
