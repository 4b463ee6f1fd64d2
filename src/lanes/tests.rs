use super::*;

/// Each lane of `T` computes bit for bit what `f64` computes.
fn lanes_compute_what_scalars_compute<T: Lanes>() {
    let xs = [1.0, -2.5, 3.0e-7, 1.0 / 3.0, 5.5e3, -0.0, 7.25, 1e-300];
    let ys = [0.1, 7.0, -1.0e9, 2.0 / 3.0, -3.0, 2.0, 7.25, 3.0];
    let (a, b): (T, T) = (gather(|l| xs[l]), gather(|l| ys[l]));
    let r = ((a * b + a - b) * -a / b).sqrt().to_array();
    let chosen = (a - b).where_positive(a, b).to_array();
    let nan = T::splat(f64::NAN).where_positive(a, b).to_array();
    let negated_zero = (-T::splat(0.0)).to_array();
    for l in 0..T::WIDTH {
        let (x, y) = (xs[l], ys[l]);
        assert_eq!(r[l].to_bits(), ((x * y + x - y) * -x / y).sqrt().to_bits());
        assert_eq!(chosen[l], (x - y).where_positive(x, y));
        assert_eq!(nan[l], y, "NaN is not positive");
        assert_eq!(negated_zero[l].to_bits(), (-0.0f64).to_bits());
        assert_eq!(T::splat(2.0).to_array()[l], 2.0);
    }
    // the kernel's loads: corner positions by node id, and records of ten f64
    let x: Vec<[f64; 3]> = (0..50)
        .map(|n| [n as f64, 0.5 - n as f64, 1e-3 * n as f64])
        .collect();
    let tets: Vec<[u32; 4]> = (0..8)
        .map(|e| [7 * e, 49 - 5 * e, 3 + e, 6 * e + 1])
        .collect();
    let records: Vec<[f64; 10]> = (0..8)
        .map(|e| build(0.0, |k| (10 * e + k) as f64 + 0.25))
        .collect();
    let tets = Connectivity::new(tets);
    let corners = T::gather_corners(&TetNodes::of(&x, &tets, 0..tets.len()), 0);
    let fields: [T; 10] = T::gather_records(&records);
    for l in 0..T::WIDTH {
        for a in 0..4 {
            for i in 0..3 {
                let want = x[tets[l][a] as usize][i];
                assert_eq!(
                    corners[a][i].to_array()[l],
                    want,
                    "corner {a}, component {i}"
                );
            }
        }
        for (k, field) in fields.iter().enumerate() {
            assert_eq!(field.to_array()[l], records[l][k], "record field {k}");
        }
    }
    // forces added into the nodes in the order of the one-element loop: lane after
    // lane, corner after corner (nodes shared between lanes, and node 7 twice in lane 1)
    let nodal: [[T; 3]; 4] = build([T::splat(0.0); 3], |a| {
        build(T::splat(0.0), |i| {
            gather(|l| ((a * 3 + i) as f64 + 0.1) / (l as f64 + 3.0))
        })
    });
    let mut added = vec![NodeForce::from([1.0 / 3.0; 3]); x.len()];
    let mut expected: Vec<[f64; 3]> = added.iter().map(NodeForce::xyz).collect();
    let nodes = TetNodes::of(&x, &tets, 0..tets.len());
    // SAFETY: `added` has one entry per position; nothing else touches it
    unsafe { T::add_corner_forces(&nodal, &nodes, 0, added.as_mut_ptr()) };
    for (l, t) in tets.iter().take(T::WIDTH).enumerate() {
        for (a, &n) in t.iter().enumerate() {
            for i in 0..3 {
                expected[n as usize][i] += nodal[a][i].to_array()[l];
            }
        }
    }
    for (n, (got, want)) in added.iter().zip(&expected).enumerate() {
        for i in 0..3 {
            assert_eq!(
                got[i].to_bits(),
                want[i].to_bits(),
                "node {n}, component {i}"
            );
        }
        // the padding stays zero: nothing is added into it
        assert_eq!(got.0[3].to_bits(), 0, "node {n}, padding");
    }
    // records whose length is not a multiple of four (the J2 state has seven fields):
    // the last block of each is a partial row
    let states: Vec<[f64; 7]> = (0..8)
        .map(|e| build(0.0, |k| -((7 * e + k) as f64) - 0.5))
        .collect();
    let fields: [T; 7] = T::gather_records(&states[..T::WIDTH]);
    for l in 0..T::WIDTH {
        for (k, field) in fields.iter().enumerate() {
            assert_eq!(field.to_array()[l], states[l][k], "state field {k}");
        }
    }
    // and back: the lanes' records written, the record after them untouched
    let mut written = vec![[f64::NAN; 7]; T::WIDTH + 1];
    T::scatter_records(&fields, &mut written);
    for (l, record) in written.iter().enumerate().take(T::WIDTH) {
        assert_eq!(
            record.map(f64::to_bits),
            states[l].map(f64::to_bits),
            "record {l}"
        );
    }
    assert!(
        written[T::WIDTH].iter().all(|v| v.is_nan()),
        "a record past the lanes was written"
    );
    let mut written = vec![[0.0; 10]; T::WIDTH + 1];
    T::scatter_records(&T::gather_records(&records[..T::WIDTH]), &mut written);
    assert_eq!(
        written[..T::WIDTH],
        records[..T::WIDTH],
        "ten-field records"
    );
    assert_eq!(written[T::WIDTH], [0.0; 10]);
}

/// A node id beyond the positions stops the gather (an index check, not a stray read).
fn a_node_id_beyond_the_positions_panics<T: Lanes>() {
    let x = vec![[0.0; 3]; 10];
    let mut tets = vec![[0u32, 1, 2, 3]; 8];
    tets[T::WIDTH - 1][2] = 10;
    // the bound found when the tetrahedra were built, whichever range is gathered
    let tets = Connectivity::new(tets);
    assert_eq!(tets.node_bound(), 11);
    let outcome =
        std::panic::catch_unwind(|| T::gather_corners(&TetNodes::of(&x, &tets, 0..T::WIDTH), 0));
    assert!(outcome.is_err(), "node 10 of 10 positions was gathered");
    let longer = vec![[0.0; 3]; 11];
    let nodes = TetNodes::of(&longer, &tets, 0..T::WIDTH);
    assert_eq!(nodes.len(), T::WIDTH);
    assert_eq!(Connectivity::new(Vec::new()).node_bound(), 0);
}

#[test]
fn avx2_lanes_compute_what_scalars_compute() {
    if !std::arch::is_x86_feature_detected!("avx2") {
        panic!("this test needs an AVX2 CPU: the kernel's fast path could not be checked");
    }
    lanes_compute_what_scalars_compute::<F64x4>();
    a_node_id_beyond_the_positions_panics::<F64x4>();
    a_node_id_beyond_the_positions_panics::<f64>();
}

#[test]
fn avx512_lanes_compute_what_scalars_compute() {
    if !(std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512vl"))
    {
        println!("no AVX-512F and VL on this CPU: the eight-lane path is never taken here");
        return;
    }
    lanes_compute_what_scalars_compute::<F64x8>();
    a_node_id_beyond_the_positions_panics::<F64x8>();
}
