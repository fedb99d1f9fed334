"""Bazel rules for otbake: every product of a manifest as one hermetic `otbake bake-one` action.

`otbake plan MANIFEST --format bazel` writes the BUILD file that calls `otbake_bake` for a
manifest; `otbake_product` is the single action, for hand-written targets.

Each action declares everything it reads and nothing else: the manifest, the product's input
file(s), the proxy archive (for maps) and the otbake binary itself. The binary is an input like any
other, so a new otbake misses every cache. Bazel does not build otbake here (Rust rules would be
fetched from the network): hand the rules a built binary as a label, e.g. a file `tools/otbake`
exported by `tools/BUILD.bazel`.

Architecture Invariant: an action reads only its declared inputs and writes only its one declared
output, so it runs the same under `--spawn_strategy=linux-sandbox`, from a disk or remote cache,
or on a remote-execution worker whose image holds nothing but what the action ships with it.
"""

def _otbake_product_impl(ctx):
    out = ctx.outputs.out
    args = ctx.actions.args()
    args.add("bake-one")
    args.add(ctx.file.manifest)
    args.add("--product", ctx.attr.product)
    inputs = [ctx.file.manifest] + ctx.files.srcs
    if ctx.attr.product == "proxy":
        if ctx.file.proxy:
            fail("%s: the proxy product takes no `proxy` attribute" % ctx.label)
    else:
        if not ctx.file.proxy:
            fail("%s: the map %r needs `proxy`, the label of its manifest's proxy product" % (ctx.label, ctx.attr.product))
        args.add("--proxy", ctx.file.proxy)
        inputs.append(ctx.file.proxy)
    args.add("-o", out)
    ctx.actions.run(
        executable = ctx.executable.otbake,
        arguments = [args],
        inputs = inputs,
        outputs = [out],
        mnemonic = "OtbakeBakeOne",
        progress_message = "otbake bake-one %s (%s)" % (ctx.attr.product, ctx.file.manifest.short_path),
    )
    return [DefaultInfo(files = depset([out]))]

otbake_product = rule(
    implementation = _otbake_product_impl,
    doc = "One product of a manifest (`proxy` or an input's map), baked by `otbake bake-one`.",
    attrs = {
        "manifest": attr.label(
            doc = "The manifest (.toml); the input paths inside it are relative to it.",
            allow_single_file = [".toml"],
            mandatory = True,
        ),
        "product": attr.string(
            doc = "`proxy`, or the name of an [[input]].",
            mandatory = True,
        ),
        "srcs": attr.label_list(
            doc = "Every input file the product reads: its input, an input proxy's file, the meshes of a common fit.",
            allow_files = True,
        ),
        "proxy": attr.label(
            doc = "For a map: the manifest's proxy product.",
            allow_single_file = [".otb"],
        ),
        "out": attr.output(
            doc = "The archive this action writes.",
            mandatory = True,
        ),
        "otbake": attr.label(
            doc = "The otbake binary (a file target or any executable label).",
            executable = True,
            cfg = "exec",
            allow_single_file = True,
            mandatory = True,
        ),
    },
)

def otbake_bake(name, manifest, otbake, maps, proxy_srcs = [], **kwargs):
    """Every product of a manifest: `NAME_proxy` and `NAME_INPUT` writing `NAME/proxy.otb` and
    `NAME/INPUT.otb`, and the filegroup `NAME` of them all.

    Args:
      name: the filegroup, and the prefix of the product targets and the output folder.
      manifest: the manifest file.
      otbake: the otbake binary's label.
      maps: {input name: [the files its map reads]}, in manifest order.
      proxy_srcs: the files the proxy reads (the proxy input's file; none for a shape proxy).
      **kwargs: common attributes (visibility, tags) for every target.
    """
    proxy = name + "_proxy"
    otbake_product(
        name = proxy,
        manifest = manifest,
        product = "proxy",
        srcs = proxy_srcs,
        out = name + "/proxy.otb",
        otbake = otbake,
        **kwargs
    )
    products = [":" + proxy]
    for product, srcs in maps.items():
        otbake_product(
            name = name + "_" + product,
            manifest = manifest,
            product = product,
            srcs = srcs,
            proxy = ":" + proxy,
            out = name + "/" + product + ".otb",
            otbake = otbake,
            **kwargs
        )
        products.append(":" + name + "_" + product)
    native.filegroup(name = name, srcs = products, **kwargs)
