//! The gate's view of a streamed file: blocks of rows kept at a doubling stride, so that
//! they always span the whole file in a bounded number of rows.
//!
//! The file is cut into blocks of [`Sketch::block_rows`] rows (the excerpt is block 0). Block
//! `i` is kept when `i` is a multiple of the stride; when more than twice
//! [`super::StreamOptions::gate_blocks`] are kept, every other one is dropped and the stride
//! doubles. So between `gate_blocks` and twice that are kept, evenly spread from the first
//! row to the last kept block, and the last [`Sketch::block_rows`] rows of the file (the
//! tail) are kept beside them: at most `2 · gate_blocks + 2` blocks are held at any time
//! (the kept ones, the one being filled, the last complete one).

use crate::recording::{Recording, Sample};

/// One block of the file: its first data row (0-based) and its rows as read.
#[derive(Clone, Debug)]
pub(super) struct Block {
    pub(super) first_row: usize,
    pub(super) rows: Recording,
}

/// Blocks kept at a doubling stride (see the module docs).
pub(super) struct Sketch {
    block_rows: usize,
    max_kept: usize,
    stride: usize,
    kept: Vec<(usize, Recording)>,
    current: Recording,
    current_index: usize,
    /// The last complete block when it was not kept (for the tail).
    last_dropped: Option<Recording>,
}

fn empty_like(template: &Recording, capacity: usize) -> Recording {
    Recording {
        path: template.path.clone(),
        t: Vec::with_capacity(capacity),
        x: Vec::with_capacity(capacity),
        v: template.v.as_ref().map(|_| Vec::with_capacity(capacity)),
        u: template.u.as_ref().map(|_| Vec::with_capacity(capacity)),
        columns: template.columns.clone(),
    }
}

impl Sketch {
    /// A sketch of blocks of `block_rows` rows, keeping `gate_blocks` to twice that,
    /// starting with the file's first rows (`head`, at most `block_rows` of them).
    pub(super) fn new(head: &Recording, block_rows: usize, gate_blocks: usize) -> Self {
        let block_rows = block_rows.max(1);
        let mut sketch = Self {
            block_rows,
            max_kept: 2 * gate_blocks.max(1),
            stride: 1,
            kept: Vec::new(),
            current: empty_like(head, block_rows),
            current_index: 0,
            last_dropped: None,
        };
        for s in head.samples() {
            sketch.push(s);
        }
        sketch
    }

    /// Takes the next row of the file.
    pub(super) fn push(&mut self, s: Sample) {
        let c = &mut self.current;
        c.t.push(s.t);
        c.x.push(s.x);
        if let (Some(values), Some(v)) = (c.v.as_mut(), s.v) {
            values.push(v);
        }
        if let (Some(values), Some(u)) = (c.u.as_mut(), s.u) {
            values.push(u);
        }
        if c.t.len() < self.block_rows {
            return;
        }
        let fresh = empty_like(c, self.block_rows);
        let full = std::mem::replace(&mut self.current, fresh);
        let index = self.current_index;
        self.current_index += 1;
        self.last_dropped = None;
        if !index.is_multiple_of(self.stride) {
            self.last_dropped = Some(full);
            return;
        }
        self.kept.push((index, full));
        if self.kept.len() > self.max_kept {
            self.stride *= 2;
            let stride = self.stride;
            for (i, block) in std::mem::take(&mut self.kept) {
                if i.is_multiple_of(stride) {
                    self.kept.push((i, block));
                } else if i == index {
                    self.last_dropped = Some(block);
                }
            }
        }
    }

    /// The kept blocks in file order, and the tail (the file's last `block_rows` rows) when
    /// it is not already among them.
    pub(super) fn finish(mut self) -> Vec<Block> {
        let block_rows = self.block_rows;
        let last_complete = self.current_index.checked_sub(1);
        let partial = self.current.len();
        // The tail: the end of the last complete block, then the partial one.
        let previous = match (&self.last_dropped, self.kept.last()) {
            (Some(dropped), _) => Some(dropped),
            (None, Some((i, block))) if Some(*i) == last_complete => Some(block),
            _ => None,
        };
        let tail = if partial == 0 {
            // The last complete block is the tail: kept already, or kept now.
            self.last_dropped.take().map(|rows| Block {
                first_row: last_complete.unwrap_or(0) * block_rows,
                rows,
            })
        } else {
            let mut tail = empty_like(&self.current, block_rows);
            let mut append = |source: &Recording, start: usize| {
                tail.t.extend_from_slice(&source.t[start..]);
                tail.x.extend_from_slice(&source.x[start..]);
                if let (Some(a), Some(b)) = (tail.v.as_mut(), source.v.as_ref()) {
                    a.extend_from_slice(&b[start..]);
                }
                if let (Some(a), Some(b)) = (tail.u.as_mut(), source.u.as_ref()) {
                    a.extend_from_slice(&b[start..]);
                }
            };
            if let Some(p) = previous {
                append(p, p.len().saturating_sub(block_rows - partial));
            }
            append(&self.current, 0);
            let end = self.current_index * block_rows + partial;
            Some(Block {
                first_row: end - tail.len(),
                rows: tail,
            })
        };
        let mut blocks: Vec<Block> = self
            .kept
            .into_iter()
            .map(|(i, rows)| Block {
                first_row: i * block_rows,
                rows,
            })
            .collect();
        blocks.extend(tail);
        blocks
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recording::ColumnNames;

    fn rows(n: usize) -> Recording {
        Recording {
            path: "f.csv".into(),
            t: (0..n).map(|i| i as f64).collect(),
            x: (0..n).map(|i| i as f64).collect(),
            v: None,
            u: None,
            columns: ColumnNames::default(),
        }
    }

    /// Every block holds consecutive rows starting where it says, the blocks are in order,
    /// their number is bounded, they reach from the first row to the last, and the kept
    /// ones are evenly spread.
    #[test]
    fn the_blocks_span_the_file_in_bounded_rows() {
        for n in [1, 9, 10, 11, 35, 99, 100, 101, 1000, 4321, 10_007] {
            for gate_blocks in [1, 2, 4] {
                let whole = rows(n);
                let mut sketch = Sketch::new(&rows(n.min(10)), 10, gate_blocks);
                for s in whole.samples().skip(10) {
                    sketch.push(s);
                    assert!(sketch.kept.len() <= 2 * gate_blocks);
                }
                let blocks = sketch.finish();
                assert!(!blocks.is_empty());
                assert!(blocks.len() <= 2 * gate_blocks + 1, "{n}: {}", blocks.len());
                assert_eq!(blocks[0].first_row, 0);
                let last = blocks.last().unwrap();
                assert_eq!(last.first_row + last.rows.len(), n, "{n} {gate_blocks}");
                for b in &blocks {
                    assert!(b.rows.len() <= 10 && !b.rows.is_empty());
                    for (k, &t) in b.rows.t.iter().enumerate() {
                        assert_eq!(t, (b.first_row + k) as f64);
                    }
                }
                for w in blocks.windows(2) {
                    assert!(w[0].first_row < w[1].first_row, "{n}");
                }
                if n >= 10 * (2 * gate_blocks + 2) {
                    // Kept blocks (all but the tail) at one stride, at least gate_blocks.
                    let kept = &blocks[..blocks.len() - 1];
                    assert!(kept.len() >= gate_blocks, "{n}: {}", kept.len());
                    let stride = kept[1].first_row - kept[0].first_row;
                    for w in kept.windows(2) {
                        assert_eq!(w[1].first_row - w[0].first_row, stride);
                    }
                    // The last kept block within two strides of the end.
                    assert!(n - kept.last().unwrap().first_row <= 2 * stride + 10);
                }
            }
        }
    }
}
