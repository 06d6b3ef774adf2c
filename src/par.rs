//! Where the parallel steps of one extraction run: on its scoped thread
//! pool, or all on the calling thread. Starting and joining a pool thread,
//! and handing work to it and back, costs about 0.1 ms a call: more than
//! contouring a small volume. Either way the steps produce the same values
//! in the same order, so the output does not depend on the choice.

use rayon::prelude::*;

/// The executor of an extraction's parallel steps.
#[derive(Clone, Copy)]
pub(crate) enum Exec<'p> {
    /// Every step on the calling thread, in order.
    Serial,
    /// Steps split over the workers of this pool.
    Pool(&'p rayon::ThreadPool),
}

impl Exec<'_> {
    /// `f` of each item, in the items' order.
    pub(crate) fn map<T, R, F>(self, items: Vec<T>, f: F) -> Vec<R>
    where
        T: Send,
        R: Send,
        F: Fn(T) -> R + Sync + Send,
    {
        match self {
            Exec::Serial => items.into_iter().map(f).collect(),
            Exec::Pool(pool) => pool.install(|| items.into_par_iter().map(f).collect()),
        }
    }

    /// Appends `f` of each element of `src` to `dst`, in order.
    pub(crate) fn extend<T, R, F>(self, dst: &mut Vec<R>, src: &[T], f: F)
    where
        T: Sync,
        R: Send,
        F: Fn(&T) -> R + Sync + Send,
    {
        match self {
            Exec::Serial => dst.extend(src.iter().map(f)),
            Exec::Pool(pool) => pool.install(|| dst.par_extend(src.par_iter().map(f))),
        }
    }

    /// Appends `n` default values to `dst` (in parallel on a pool, so that
    /// each worker first touches, and faults in, its own pages).
    pub(crate) fn fill_default<T>(self, dst: &mut Vec<T>, n: usize)
    where
        T: Default + Clone + Send + Sync,
    {
        match self {
            Exec::Serial => dst.resize(dst.len() + n, T::default()),
            Exec::Pool(pool) => {
                pool.install(|| dst.par_extend(rayon::iter::repeat_n(T::default(), n)))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_executors_give_the_same_values_in_order() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap();
        let src: Vec<u64> = (0..10_000).map(|i| i * 7919 % 10_007).collect();
        let mut out = Vec::new();
        for exec in [Exec::Serial, Exec::Pool(&pool)] {
            let mapped = exec.map(src.clone(), |x| x * x + 1);
            let mut extended = vec![5u64];
            exec.extend(&mut extended, &src, |&x| x ^ 0x55);
            let mut filled = vec![9u32];
            exec.fill_default(&mut filled, 1000);
            out.push((mapped, extended, filled));
        }
        assert_eq!(out[0], out[1]);
        assert_eq!(out[0].0[3], src[3] * src[3] + 1);
        assert_eq!(out[0].1.len(), 10_001);
        assert_eq!(out[0].1[1], src[0] ^ 0x55);
        assert_eq!(out[0].2.len(), 1001);
        assert!(out[0].2[0] == 9 && out[0].2[1..].iter().all(|&x| x == 0));
    }
}
