"""``pgm demo``: a synthetic scene rendered, tracked by three models, every output written.

The demo needs no data: it is the first thing a new user runs (the README's first
command).
"""

from __future__ import annotations


def cmd_demo(args) -> int:
    from pgm.app.runner import track
    from pgm.core.rng import as_generator
    from pgm.io.annotations import load_single_gt
    from pgm.io.outputs import prepare_run_folder
    from pgm.io.video import open_source
    from pgm.models import colour_pf, part_graph, single_object
    from pgm.synthetic import demo_scene

    out = prepare_run_folder(args.out)
    seq = demo_scene(seed=args.seed, n_frames=args.frames)
    scene_dir = out / "scene"
    seq.write_otb(scene_dir, obj_index=0)
    gt = load_single_gt(scene_dir / "groundtruth_rect.txt")
    x, y, w, h = gt.boxes[0]
    box = (x + w / 2, y + h / 2, w, h)
    runs = [("colour PF (one node)", out,
             colour_pf.build_graph(colour_pf.Params(init_box=box,
                                                    num_particles=args.particles))),
            ("part graph (two nodes)", out / "part-graph",
             part_graph.build_graph(part_graph.Params(init_box=box, n_parts=2))),
            ("single-object (the default)", out / "single-object",
             single_object.build_graph(single_object.Params(   # as pgm track builds it
                 init_box=box, frame_size=seq.frames[0].shape[1::-1])))]
    results = []
    for label, folder, graph in runs:
        folder = prepare_run_folder(folder)
        graph.draw(folder / "graph.png")
        (folder / "graph.dot").write_text(graph.to_dot())
        results.append((label, track(open_source(scene_dir), graph, rng=as_generator(args.seed),
                                     out_dir=folder, gt=gt, show_particles=True,
                                     progress=not args.quiet)))
    print(f"demo: synthetic scene ({len(results[0][1].frames)} frames; the walker's lower half "
          f"passes behind a magazine) in {scene_dir}")
    print(f"demo: wrote tracks.txt, annotated.mp4, metrics.json, graph.png under {out} (colour "
          f"PF), {out / 'part-graph'} and {out / 'single-object'}")
    width = max(len(label) for label, _ in results)
    print(f"{'tracker':<{width}}  success AUC  precision@20px  frames/s")
    for label, r in results:
        m = r.metrics
        print(f"{label:<{width}}  {m['success_auc']:11.3f}  {m['precision_at_20']:14.3f}  "
              f"{r.fps:8.0f}")
    return 0
