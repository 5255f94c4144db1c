//! Layered (Sugiyama-style) layout of a graph drawn left to right: cycles broken by reversing
//! the edges a depth-first search finds going back, layers by longest path from the sources,
//! crossings reduced by barycentre sweeps, then columns and rows packed from the boxes' sizes.
//! Pure: no egui, no diagram; `Diagram::arrange` feeds it blocks and links.
//!
//! Written here rather than taken from crates.io: `layout-rs` lays out for its own SVG/DOT
//! output with its own node shapes (no per-node sizes in, positions out), and `rust-sugiyama`
//! works on point-sized vertices; both would need converting to and from, for about the size of
//! this file.

/// Gap between columns (where the wires run) and between boxes of one column, in canvas units.
pub const COLUMN_GAP: f32 = 90.0;
pub const ROW_GAP: f32 = 36.0;
/// Barycentre sweeps (each one down and back up): a few are enough on systems this size.
const SWEEPS: usize = 6;

/// Top-left corners for boxes of `sizes` (`[width, height]`), with `edges` (from, to) between
/// indices into `sizes`, laid out left to right from `origin`. Edges to unknown indices and
/// self-loops are ignored.
pub fn layered(sizes: &[[f32; 2]], edges: &[(usize, usize)], origin: [f32; 2]) -> Vec<[f32; 2]> {
    let count = sizes.len();
    let edges: Vec<(usize, usize)> = edges
        .iter()
        .copied()
        .filter(|&(from, to)| from != to && from < count && to < count)
        .collect();
    let edges = acyclic(count, &edges);
    let layers = longest_path_layers(count, &edges);
    let order = reduce_crossings(count, &edges, &layers);
    place(sizes, &order, origin)
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

/// Columns as wide as their widest box, boxes stacked in each column and the columns centred on
/// one another vertically.
fn place(sizes: &[[f32; 2]], order: &[Vec<usize>], origin: [f32; 2]) -> Vec<[f32; 2]> {
    let mut positions = vec![origin; sizes.len()];
    let heights: Vec<f32> = order
        .iter()
        .map(|layer| {
            let boxes: f32 = layer.iter().map(|&node| sizes[node][1]).sum();
            boxes + ROW_GAP * layer.len().saturating_sub(1) as f32
        })
        .collect();
    let tallest = heights.iter().copied().fold(0.0, f32::max);
    let mut x = origin[0];
    for (layer, height) in order.iter().zip(heights) {
        let mut y = origin[1] + (tallest - height) / 2.0;
        let mut width: f32 = 0.0;
        for &node in layer {
            positions[node] = [x, y];
            y += sizes[node][1] + ROW_GAP;
            width = width.max(sizes[node][0]);
        }
        x += width + COLUMN_GAP;
    }
    positions
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
        let positions = layered(&sizes, &edges, [40.0, 40.0]);
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
}
