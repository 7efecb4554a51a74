//! Sample blocks and the fixed merge tree that makes a film's floating-point sums independent of
//! how a render is split. A render's samples fall into numbered blocks; the film is defined as
//! the merge of the blocks along one binary tree whose nodes are the aligned dyadic ranges
//! [j·2^k, (j+1)·2^k), folded from the left over the largest such ranges that tile [0, n). Any
//! part of the render (a contiguous block range) keeps its largest aligned ranges ("pieces");
//! merging the parts' pieces sibling by sibling rebuilds the same nodes, so the merged film is
//! bit-identical to the single run however the parts were cut (docs/rendering.md, "Sharded
//! renders"). Floating-point merges are not associative, which is why the tree is fixed.

use std::ops::Range;

/// A node of the merge tree: blocks [start, start + 2^level).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Span {
    /// First block.
    pub start: u64,
    /// log2 of the number of blocks.
    pub level: u32,
}

impl Span {
    /// One past the last block.
    pub fn end(&self) -> u64 {
        self.start + (1u64 << self.level)
    }

    /// Whether `self` is the left sibling of `right` (same size, adjacent, and their union is
    /// itself a node of the tree).
    fn left_sibling_of(&self, right: &Span) -> bool {
        self.level == right.level
            && self.level < 63
            && self.end() == right.start
            && self.start.is_multiple_of(1u64 << (self.level + 1))
    }
}

/// A node with its state.
#[derive(Debug, Clone, PartialEq)]
pub struct Piece<T> {
    /// The blocks it covers.
    pub span: Span,
    /// Their merged state.
    pub state: T,
}

/// Pushes `piece` onto `stack` and merges siblings while the two top pieces are siblings
/// (`merge(left, right)` folds the right state into the left one).
fn push_piece<T>(stack: &mut Vec<Piece<T>>, piece: Piece<T>, merge: &impl Fn(&mut T, &T)) {
    stack.push(piece);
    while stack.len() >= 2 {
        let n = stack.len();
        if !stack[n - 2].span.left_sibling_of(&stack[n - 1].span) {
            break;
        }
        let right = stack.pop().expect("two pieces");
        let left = stack.last_mut().expect("two pieces");
        merge(&mut left.state, &right.state);
        left.span.level += 1;
    }
}

/// Merges the blocks of one part, given in order with their first block `first`: the part's
/// pieces, in order.
pub struct BlockFold<T> {
    next: u64,
    stack: Vec<Piece<T>>,
}

impl<T> BlockFold<T> {
    /// A fold whose first block is `first`.
    pub fn new(first: u64) -> Self {
        BlockFold {
            next: first,
            stack: Vec::new(),
        }
    }

    /// Adds the next block's state.
    pub fn push(&mut self, state: T, merge: &impl Fn(&mut T, &T)) {
        let span = Span {
            start: self.next,
            level: 0,
        };
        self.next += 1;
        push_piece(&mut self.stack, Piece { span, state }, merge);
    }

    /// Adds a piece (a node of the tree: a single block or a merged part of one), the next
    /// in block order.
    pub fn push_piece(&mut self, piece: Piece<T>, merge: &impl Fn(&mut T, &T)) {
        self.next = piece.span.end();
        push_piece(&mut self.stack, piece, merge);
    }

    /// The pieces so far, in block order.
    pub fn into_pieces(self) -> Vec<Piece<T>> {
        self.stack
    }

    /// The merged state of a whole run (a fold that started at block 0 and has taken every
    /// block): its pieces folded from the left. None if no block was pushed.
    pub fn finish(self, merge: &impl Fn(&mut T, &T)) -> Option<T> {
        let mut it = self.stack.into_iter();
        let mut acc = it.next()?.state;
        for p in it {
            merge(&mut acc, &p.state);
        }
        Some(acc)
    }
}

/// The spans a part covering `blocks` ends with (the same for every pixel of a film).
pub fn spans(blocks: Range<u64>) -> Vec<Span> {
    let mut fold = BlockFold::new(blocks.start);
    for _ in blocks {
        fold.push((), &|_, _| {});
    }
    fold.into_pieces().into_iter().map(|p| p.span).collect()
}

/// Why parts do not make a whole.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TilingError {
    /// Some blocks are in no part.
    #[error("blocks {}..{} are in no part", .0.start, .0.end)]
    Missing(Range<u64>),
    /// Some blocks are in two parts.
    #[error("blocks {}..{} are in more than one part", .0.start, .0.end)]
    Overlap(Range<u64>),
}

/// Checks that `spans` (in any order) cover blocks [0, total) exactly once.
pub fn check_tiling(spans: &[Span], total: u64) -> Result<(), TilingError> {
    let mut sorted = spans.to_vec();
    sorted.sort_by_key(|s| s.start);
    let mut at = 0;
    for s in &sorted {
        if s.start > at {
            return Err(TilingError::Missing(at..s.start));
        }
        if s.start < at {
            return Err(TilingError::Overlap(s.start..at.min(s.end())));
        }
        at = s.end();
    }
    if at < total {
        return Err(TilingError::Missing(at..total));
    }
    if at > total {
        return Err(TilingError::Overlap(total..at));
    }
    Ok(())
}

/// Merges the pieces of parts that together cover blocks [0, total) exactly once (in any
/// order) into the single run's state; `Ok(None)` for `total` = 0.
pub fn merge_parts<T>(
    mut pieces: Vec<Piece<T>>,
    total: u64,
    merge: impl Fn(&mut T, &T),
) -> Result<Option<T>, TilingError> {
    let spans: Vec<Span> = pieces.iter().map(|p| p.span).collect();
    check_tiling(&spans, total)?;
    pieces.sort_by_key(|p| p.span.start);
    let mut fold = BlockFold::new(0);
    for p in pieces {
        fold.push_piece(p, &merge);
    }
    Ok(fold.finish(&merge))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A non-associative merge: the state is the bracketed expression itself.
    fn bracket(a: &mut String, b: &String) {
        *a = format!("({a}+{b})");
    }

    fn part(blocks: Range<u64>) -> Vec<Piece<String>> {
        let mut fold = BlockFold::new(blocks.start);
        for b in blocks {
            fold.push(b.to_string(), &bracket);
        }
        fold.into_pieces()
    }

    fn whole(total: u64) -> String {
        let mut fold = BlockFold::new(0);
        for b in 0..total {
            fold.push(b.to_string(), &bracket);
        }
        fold.finish(&bracket).unwrap()
    }

    #[test]
    fn a_whole_run_is_the_fixed_tree() {
        assert_eq!(whole(1), "0");
        assert_eq!(whole(4), "((0+1)+(2+3))");
        assert_eq!(whole(7), "((((0+1)+(2+3))+(4+5))+6)");
        assert_eq!(
            spans(0..7),
            [
                Span { start: 0, level: 2 },
                Span { start: 4, level: 1 },
                Span { start: 6, level: 0 }
            ]
        );
    }

    #[test]
    fn any_cut_merges_to_the_same_expression() {
        // every way of cutting [0, n) into contiguous parts, n up to 12, parts merged in
        // reverse order
        for n in 1..=12u64 {
            let expected = whole(n);
            for cuts in 0..(1u32 << (n - 1)) {
                let mut bounds = vec![0];
                bounds.extend((1..n).filter(|i| cuts & (1 << (i - 1)) != 0));
                bounds.push(n);
                let pieces: Vec<_> = bounds
                    .windows(2)
                    .rev()
                    .flat_map(|w| part(w[0]..w[1]))
                    .collect();
                let merged = merge_parts(pieces, n, bracket).unwrap().unwrap();
                assert_eq!(merged, expected, "n {n}, cuts {bounds:?}");
            }
        }
    }

    #[test]
    fn missing_and_overlapping_blocks_are_named() {
        let mut pieces = part(0..3);
        pieces.extend(part(5..8));
        assert_eq!(
            merge_parts(pieces, 8, bracket),
            Err(TilingError::Missing(3..5))
        );
        let mut pieces = part(0..5);
        pieces.extend(part(3..8));
        assert_eq!(
            merge_parts(pieces, 8, bracket),
            Err(TilingError::Overlap(3..4))
        );
        assert_eq!(
            merge_parts(part(0..5), 8, bracket),
            Err(TilingError::Missing(5..8))
        );
        assert_eq!(
            merge_parts(part(0..9), 8, bracket),
            Err(TilingError::Overlap(8..9))
        );
        assert_eq!(
            merge_parts(Vec::<Piece<String>>::new(), 0, bracket),
            Ok(None)
        );
    }
}
