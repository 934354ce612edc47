"""``carbody render-dataset``, ``carbody end-looks``, ``carbody train-view`` and ``carbody view``."""
from __future__ import annotations

import argparse


def add_parsers(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("render-dataset", help="render the multi-view car data set for the view classifier",
                       description="Render library bodies (templates and expansions, surfaced by carbody) "
                                   "off-screen at 24 view classes (0-345 deg by 15; the right side is the "
                                   "mirror image of the left) with random paint, glass, light, elevation "
                                   "0-30 deg, distance, crop and background. Split by car 8:2.")
    p.add_argument("out_dir", help="folder to write (images/<angle>/*.png, manifest.csv, dataset.json)")
    p.add_argument("--count", type=int, default=None, help="number of images (default 3096)")
    p.add_argument("--seed", type=int, default=0, help="random seed; the same seed gives the same data set")
    p.add_argument("--bodies-per-template", type=int, default=4,
                   help="each template plus this many - 1 library expansions (default 4)")
    p.add_argument("--plain", action="store_true", help="no variation of background, colour or camera (ablation)")
    p.add_argument("--no-background", action="store_true", help="plain white backgrounds (ablation)")
    p.add_argument("--no-colour", action="store_true", help="one paint, glass and light (ablation)")
    p.add_argument("--no-elevation", action="store_true", help="fixed 10 deg elevation, centred, orthographic (ablation)")
    p.add_argument("--photo-like", action="store_true",
                   help="photo-like renders: a camera at a person's height 3-15 m from the car, ground and "
                        "contact shadow, environment-lit paint and glass, plates, street backdrops, camera "
                        "artefacts, framed as a photo's car box is cropped, lamps, grilles and mirrors")
    p.add_argument("--photo-off", default="", metavar="PARTS",
                   help="with --photo-like, switch these parts off (ablation; comma-separated: camera, "
                        "ground, environment, backdrop, artefacts, plates, framing, details, sharp)")
    p.add_argument("--photo-fraction", type=float, default=1.0,
                   help="with --photo-like, the share of photo-like images (the rest classic; default 1)")
    p.add_argument("--blends", type=int, default=0,
                   help="this many more bodies, each a random mix of two training templates")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="render on a running Dask cluster (tcp://host:8786) whose workers see OUT_DIR at the "
                        "same path; the images are the same bit for bit as in one process")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="render on a local Dask cluster of N worker processes (default: in this process)")
    p.set_defaults(func=_render_dataset)

    p = sub.add_parser("train-view", help="train the view classifier (MobileNetV2) on a rendered data set",
                       description="Train MobileNetV2 from scratch (or from --init): 64x64 input unless "
                                   "--input-size, Adam lr 0.001 (cosine decay), 50 epochs, batch 64, the data "
                                   "set's 8:2 split by car. Writes the weights (fp16) and a loss/accuracy plot "
                                   "(paper Fig. 5).")
    p.add_argument("dataset", nargs="+",
                   help="folder written by render-dataset (or class folders named by angle); several are "
                        "trained on together (rendered with the same --seed, so they hold out the same cars)")
    p.add_argument("-o", "--output", required=True, help="weights file to write (.pt)")
    p.add_argument("--epochs", type=int, default=50)
    p.add_argument("--batch-size", type=int, default=64)
    p.add_argument("--lr", type=float, default=0.001)
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads (default 1)")
    p.add_argument("--schedule", choices=("constant", "cosine"), default="cosine",
                   help="learning rate: cosine decay from --lr to 0 (default, as shipped) or "
                        "constant (the paper's setting)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--plot", default=None, help="loss/accuracy PNG (default: OUTPUT with .png)")
    p.add_argument("--init", default=None, metavar="W.pt", help="start from these weights instead of from scratch")
    p.add_argument("--zoom", action="store_true", help="augment with a random zoom of 0.85-1.2 (an inexact box)")
    p.add_argument("--erase", action="store_true",
                   help="augment by filling a random rectangle with noise in half of the pictures (random erasing)")
    p.add_argument("--input-size", type=int, default=64, metavar="PX",
                   help="network input side in pixels (default 64, the paper's)")
    p.add_argument("--resume", action="store_true",
                   help="go on from OUTPUT.ckpt (written after every epoch) if an earlier run was interrupted")
    p.add_argument("--no-calibrate", action="store_true",
                   help="do not fit the temperature on the validation split after training")
    p.set_defaults(func=_train_view)

    p = sub.add_parser("end-looks", help="write the near end's looks of a set of framed renders",
                       description="Copy a render-dataset folder's framed three-quarter views (--photo-like) "
                                   "with everything beyond 40-60 %% of the car's box from its near end painted "
                                   "grey: the second look carbody view takes to tell which way a car faces. "
                                   "Train on it beside the renders (train-view SRC DST ...).")
    p.add_argument("src", help="folder written by render-dataset --photo-like")
    p.add_argument("dst", help="new folder to write (images/<angle>/*.png, manifest.csv, dataset.json)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the share of the box kept")
    p.set_defaults(func=_end_looks)

    p = sub.add_parser("calibrate-view", help="fit the view classifier's temperature on rendered held-out cars",
                       description="Fit one temperature T (logits / T before the softmax) that minimises the "
                                   "negative log-likelihood of a rendered data set's images of the cars the "
                                   "weights were not trained on, with mirror averaging as carbody view does, and store it "
                                   "in the weights file, so the probabilities reported are calibrated.")
    p.add_argument("dataset", nargs="+",
                   help="folder written by render-dataset (its images of the weights' held-out cars are used); "
                        "several are read together")
    p.add_argument("--weights", required=True, help="weights file to calibrate (rewritten in place)")
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads (default 1)")
    p.set_defaults(func=_calibrate_view)

    p = sub.add_parser("soup-view", help="average view classifiers fine-tuned from the same weights (a model soup)",
                       description="Write the mean of the weights of two or more view classifiers fine-tuned "
                                   "from the same weights (train-view --init) and holding out the same cars: a "
                                   "uniform model soup, one network of the same size whose seeds' spread "
                                   "averages out. Then fit its temperature on rendered held-out cars "
                                   "(--calibrate, as calibrate-view does).")
    p.add_argument("weights", nargs="+", help="weights files (.pt) to average")
    p.add_argument("-o", "--output", required=True, help="weights file to write (.pt)")
    p.add_argument("--calibrate", nargs="+", default=None, metavar="DATASET",
                   help="rendered data set folder(s) to fit the soup's temperature on (else it is 1: "
                        "run calibrate-view before using the soup)")
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads (default 1)")
    p.set_defaults(func=_soup_view)

    p = sub.add_parser("view", help="tell the view angle of a car picture",
                       description="Classify the view angle of a car picture with the shipped MobileNetV2: "
                                   "class (0-345 deg by 15; 0 front, 90 left side, 180 rear, 270 right side), "
                                   "continuous estimate and class probabilities.")
    p.add_argument("image", help="picture file (PNG, JPEG, ...; gray, RGB or RGBA)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.add_argument("--weights", default=None, help="weights file (default: the shipped ones)")
    crop = p.add_mutually_exclusive_group()
    crop.add_argument("--box", type=float, nargs=4, metavar=("X0", "Y0", "X1", "Y1"), default=None,
                      help="the car's box in pixels (u right, v down): the picture is cropped to it as "
                           "the training renders frame their cars; much better when the car fills "
                           "little of the photo. A three-quarter view gets a second look at the car's "
                           "near end, which tells which way it faces")
    crop.add_argument("-k", "--keypoints", default=None, metavar="FILE",
                      help="keypoint file of the picture (project JSON, COCO, labelme): crop to the box "
                           "of its marks, grown by 12 %% of its larger side, and weigh the views by "
                           "which of them could see the marked keypoints")
    p.set_defaults(func=_view)


def _render_dataset(args) -> int:
    from carbody.view.dataset import DEFAULT_COUNT, Variation, render_dataset

    from carbody.errors import ViewError
    from carbody.view.photo import PhotoLook

    photo = None
    if args.photo_like:
        off = {x.strip() for x in args.photo_off.split(",") if x.strip()}
        unknown = off - set(PhotoLook.__dataclass_fields__)
        if unknown:
            raise ViewError(f"--photo-off: unknown part {sorted(unknown)[0]!r} "
                            f"(one of {', '.join(PhotoLook.__dataclass_fields__)})")
        photo = PhotoLook(**{k: k not in off for k in PhotoLook.__dataclass_fields__})
    if not 0.0 <= args.photo_fraction <= 1.0:
        raise ViewError(f"--photo-fraction must be within 0..1, got {args.photo_fraction}")
    vary = Variation(background=not (args.plain or args.no_background), colour=not (args.plain or args.no_colour),
                     elevation=not (args.plain or args.no_elevation), photo=photo, photo_fraction=args.photo_fraction)
    kw = dict(count=args.count or DEFAULT_COUNT, seed=args.seed, bodies_per_template=args.bodies_per_template,
              vary=vary, blends=args.blends, progress=not args.quiet)
    if args.scheduler is None and args.workers is None:
        manifest = render_dataset(args.out_dir, **kw)
    else:
        from carbody.cluster import connect

        with connect(args.scheduler, args.workers, warm=("kernel",)) as client:
            manifest = render_dataset(args.out_dir, **kw, client=client)
    print(manifest)
    return 0


def _train_view(args) -> int:
    from carbody.outputs import check_output_file
    from carbody.view.train import TrainConfig, train_view_classifier

    check_output_file(args.output)  # before hours of training, not after
    cfg = TrainConfig(epochs=args.epochs, batch_size=args.batch_size, lr=args.lr, seed=args.seed,
                      threads=args.threads, schedule=args.schedule, zoom=args.zoom, erase=args.erase,
                      init=args.init, input_size=args.input_size,
                      resume=args.resume)
    hist = train_view_classifier(args.dataset, args.output, cfg, plot=args.plot, progress=not args.quiet)
    print(f"{args.output}: validation accuracy {hist.val_acc[-1]:.3f} after {len(hist.val_acc)} epochs "
          f"({hist.seconds:.0f} s)")
    if not args.no_calibrate:
        from carbody.view.calibrate import calibrate_weights

        r = calibrate_weights(args.output, args.dataset, progress=False)
        print(f"temperature {r['temperature']:.3f} on {r['images']} held-out renders (ECE {r['ece_before']:.3f} "
              f"-> {r['ece_after']:.3f})")
    return 0


def _end_looks(args) -> int:
    from carbody.view.ends import write_end_looks

    n = write_end_looks(args.src, args.dst, seed=args.seed)
    print(f"{args.dst}: {n} end looks of {args.src}'s framed three-quarter views")
    return 0


def _calibrate_view(args) -> int:
    import torch

    from carbody.view.calibrate import calibrate_weights

    torch.set_num_threads(max(1, args.threads))
    r = calibrate_weights(args.weights, args.dataset)
    print(f"{args.weights}: temperature {r['temperature']:.3f} on {r['images']} held-out renders; "
          f"NLL {r['nll_before']:.3f} -> {r['nll_after']:.3f}, ECE {r['ece_before']:.3f} -> {r['ece_after']:.3f}")
    return 0


def _soup_view(args) -> int:
    import torch

    from carbody.occ.step_curves import atomic_write
    from carbody.outputs import check_output_file
    from carbody.view.train import average_weights, check_soup_output

    out = check_output_file(args.output)
    check_soup_output(args.weights, out)
    if args.calibrate:
        from carbody.view.dataset import read_datasets

        read_datasets(args.calibrate)  # a bad folder refused before anything is written
    done = {}

    def write(tmp) -> None:  # averaged and calibrated beside the output: a failed calibration leaves no file
        done["soup"] = average_weights(args.weights, tmp)
        if args.calibrate:
            from carbody.view.calibrate import calibrate_weights

            torch.set_num_threads(max(1, args.threads))
            done["calibration"] = calibrate_weights(tmp, args.calibrate, progress=False)

    atomic_write(out, write)
    print(f"{out}: the mean of {len(done['soup']['soup'])} networks fine-tuned from {done['soup']['config']['init']}")
    if args.calibrate:
        r = done["calibration"]
        print(f"temperature {r['temperature']:.3f} on {r['images']} held-out renders (ECE {r['ece_before']:.3f} "
              f"-> {r['ece_after']:.3f})")
    else:
        print("temperature 1: run calibrate-view on rendered held-out cars before using it")
    return 0


def _view(args) -> int:
    import json

    from carbody.view.predict import predict_view

    from carbody.view.predict import keypoint_box

    box, marks, image = args.box, None, args.image
    if args.keypoints:
        from carbody.fit.keypoints_io import check_on_image, read_keypoints
        from carbody.view.predict import read_image

        marks = read_keypoints(args.keypoints).points
        image = read_image(args.image)
        check_on_image(marks, (image.shape[1], image.shape[0]))  # a mark far off would crop a vast square
        box = keypoint_box(marks)
    p = predict_view(image, weights=args.weights, box=box, marks=marks)
    if args.json:
        out = p.as_dict()
        if box is not None:
            out["box"] = [round(float(v), 1) for v in box]
        print(json.dumps(out, indent=1))
        return 0
    top = sorted(range(len(p.probabilities)), key=lambda k: -p.probabilities[k])[:3]
    from carbody.view.labels import CLASS_ANGLES_DEG

    others = ", ".join(f"{int(CLASS_ANGLES_DEG[k])}° {p.probabilities[k]:.2f}" for k in top)
    where = "" if box is None else " in box " + " ".join(f"{v:.0f}" for v in box)
    print(f"view {int(p.class_deg)}° ({p.side}; paper class {int(p.paper_class_deg)}°), estimate "
          f"{p.theta_deg:.1f}°, confidence {p.confidence:.2f}  [top: {others}]{where}")
    return 0
