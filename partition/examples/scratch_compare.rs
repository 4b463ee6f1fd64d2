use partition::*;
use std::time::Instant;
fn main() {
    let r = 1.1e-3;
    let grains: Vec<GrainInfo> = fcc_packing(2000, r).into_iter().map(|centre| GrainInfo{centre, bounding_radius:r, elements:8000, surface_nodes:1500}).collect();
    let g = GrainGraph::build(&grains, 0.1*r, &CostModel::default());
    let xadj: Vec<i32> = g.xadj().iter().map(|&x| x as i32).collect();
    let adj: Vec<i32> = g.adjncy().iter().map(|&x| x as i32).collect();
    let aw: Vec<i32> = g.adjwgt().iter().map(|&x| x as i32).collect();
    let vw: Vec<i32> = g.vertex_weights().iter().map(|&x| x as i32).collect();
    for parts in [2usize,4,8,16,32,64,128,256,512,1024] {
        for (name, rec, ncuts) in [("kway",false,1),("kway-ncuts4",false,4),("rec",true,1)] {
            let mut p = vec![0i32; 2000];
            let t = Instant::now();
            let gr = metis::Graph::new(1, parts as i32, &xadj, &adj).unwrap().set_vwgt(&vw).set_adjwgt(&aw).set_option(metis::option::Seed(0)).set_option(metis::option::NCuts(ncuts));
            if rec { gr.part_recursive(&mut p).unwrap(); } else { gr.part_kway(&mut p).unwrap(); }
            let dt = t.elapsed().as_secs_f64()*1e3;
            let pu: Vec<u32> = p.iter().map(|&x| x as u32).collect();
            let m = metrics(&g, &grains, &pu, parts).unwrap();
            let empty = m.grains_per_part.iter().filter(|&&n| n==0).count();
            println!("{parts:5} {name:12} imb {:6.2}% cut {:7} ghosts max {:4} halo {:8.1}MB maxpart {:6.2}MB empty {empty} {dt:7.2} ms", 100.0*m.imbalance, m.edge_cut, m.max_ghost_grains(), m.halo_bytes_per_step as f64/1e6, m.max_halo_bytes_per_part() as f64/1e6);
        }
    }
}
