#!/usr/bin/python3
"""deploy/packages.txt is the one package list, and it is complete.

./imca and both Dockerfiles install from it and from nothing else; every
shared library the shipped binaries load belongs to a package tagged runtime
(the ones they link directly) or pulled in by one (the rest), but for a short
allowance of what debian:12 itself holds; every package that CMake's
find_package/pkg_check_modules find is tagged build. A dependency added in one
place only fails here.
"""
import os
import re
import subprocess
import tempfile
import unittest

ROOT = os.environ.get("IMCA_ROOT", os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BIN = os.environ.get("IMCA_BIN", os.path.join(ROOT, "build", "bin"))
LIST = os.path.join(ROOT, "deploy", "packages.txt")
TAGS = ("build", "runtime", "host", "test", "deploy", "prometheus")
# What the image ships (deploy/Dockerfile's runtime stage copies these).
SHIPPED = ("reward_server", "learner", "actor", "imca_env", "imca_health")
# In every debian:12, so never listed: the C library, the C++ runtime, zlib.
# (Checked below to be part of Debian's essential/required set.)
BASE = {"libc6", "libstdc++6", "libgcc-s1", "zlib1g"}
# The Dockerfiles and the tag each stage installs.
DOCKERFILES = {os.path.join("deploy", "Dockerfile"): {"build": "build", "runtime": "runtime"},
               os.path.join("deploy", "prometheus", "Dockerfile"): {None: "prometheus"}}
# find_package modules that find no package of their own.
NOT_PACKAGES = {"Threads", "PkgConfig"}
PKG_KEYWORDS = {"REQUIRED", "QUIET", "IMPORTED_TARGET", "GLOBAL", "NO_CMAKE_PATH", "NO_CMAKE_ENVIRONMENT_PATH"}
# Folders every -dev package installs into: they name no package.
SHARED_DIRS = {"/usr/include", "/usr/lib", "/usr/lib/x86_64-linux-gnu", "/usr/share", "/usr", "/usr/bin"}


def read_list(path=LIST):
    """{package: set of tags} (the reference reader)."""
    packages = {}
    with open(path) as f:
        for n, line in enumerate(f, 1):
            words = line.split("#", 1)[0].split()
            if not words:
                continue
            assert len(words) == 2, f"{path}:{n}: want 'package tag[,tag...]', got {line.strip()!r}"
            name, tags = words[0], set(words[1].split(","))
            assert name not in packages, f"{path}:{n}: {name} listed twice"
            assert tags <= set(TAGS), f"{path}:{n}: unknown tag in {tags - set(TAGS)}"
            packages[name] = tags
    return packages


def tagged(packages, tag):
    return {p for p, tags in packages.items() if tag in tags}


def owners(paths):
    """{path: set of packages} via dpkg -S, trying the /usr-merged twin of each path."""
    candidates = {}
    for path in paths:
        twins = {path, os.path.realpath(path)}
        for p in list(twins):
            if p.startswith("/usr/"):
                twins.add(p[4:])
            elif p.startswith(("/lib", "/bin", "/sbin")):
                twins.add("/usr" + p)
        candidates[path] = twins
    every = sorted({p for twins in candidates.values() for p in twins})
    out = subprocess.run(["dpkg", "-S", *every], capture_output=True, text=True).stdout
    found = {}
    for line in out.splitlines():
        names, _, path = line.partition(": ")
        if path and not names.startswith("diversion"):
            found.setdefault(path.strip(), set()).update(n.split(":")[0].strip() for n in names.split(","))
    return {path: set().union(*(found.get(p, set()) for p in twins)) for path, twins in candidates.items()}


def through_alternatives(path):
    """Whether the symbolic links from `path` pass through /etc/alternatives."""
    for _ in range(40):
        if not os.path.islink(path):
            return False
        path = os.path.join(os.path.dirname(path), os.readlink(path))
        if path.startswith("/etc/alternatives/"):
            return True
    return False


def installed():
    """{package: (dependency alternatives, provides, essential or required)} of the installed packages."""
    out = subprocess.run(["dpkg-query", "-W", "-f",
                          "${Package}\t${db:Status-Status}\t${Depends}, ${Pre-Depends}\t${Provides}\t${Essential}"
                          "\t${Priority}\n"], capture_output=True, text=True, check=True).stdout
    packages = {}
    for line in out.splitlines():
        name, status, depends, provides, essential, priority = line.split("\t")
        if status != "installed":
            continue
        alternatives = [[re.sub(r"[:(].*", "", a).strip() for a in d.split("|")] for d in depends.split(",")]
        packages[name] = ([a for a in alternatives if a and a[0]],
                          {re.sub(r"[:(].*", "", p).strip() for p in provides.split(",") if p.strip()},
                          essential == "yes" or priority == "required")
    return packages


def closure(roots, db):
    """Every installed package `roots` pull in through Depends/Pre-Depends."""
    providers = {}
    for name, (_, provides, _) in db.items():
        for virtual in provides | {name}:
            providers.setdefault(virtual, set()).add(name)
    seen, todo = set(), [r for r in roots if r in db]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        for alternatives in db[name][0]:
            for a in alternatives:
                todo += sorted(providers.get(a, ()))
    return seen


def dockerfile_runs(path):
    """(stage name, instruction, text) of each instruction, continuation lines joined."""
    with open(os.path.join(ROOT, path)) as f:
        text = re.sub(r"\\\n", " ", f.read())
    stage, out = None, []
    for line in text.splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        instruction, _, rest = line.partition(" ")
        if instruction.upper() == "FROM":
            m = re.search(r"\bAS (\S+)$", rest, re.I)
            stage = m.group(1) if m else None
        out.append((stage, instruction.upper(), rest))
    return out


def substitution(args):
    """(the first $(...) command in args, args without it), parentheses balanced."""
    start = args.find("$(")
    if start < 0:
        return "", args
    depth = 0
    for i in range(start + 1, len(args)):
        depth += {"(": 1, ")": -1}.get(args[i], 0)
        if depth == 0:
            return args[start + 2:i], args[:start] + args[i + 1:]
    raise AssertionError(f"unbalanced $( in {args}")


class PackageListTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.packages = read_list()
        cls.db = installed()

    def test_imca_reads_the_list(self):
        for tag in TAGS:
            r = subprocess.run([os.path.join(ROOT, "imca"), "packages", "--list", tag], capture_output=True,
                               text=True, check=True)
            self.assertEqual(r.stdout.split(), [p for p, t in self.packages.items() if tag in t], tag)
        # ... and installs only what it read from it.
        with open(os.path.join(ROOT, "imca")) as f:
            script = re.sub(r"\\\n", " ", f.read())
        installs = re.findall(r"apt-get install(.*)", script)
        self.assertTrue(installs)
        for args in installs:
            self.assertEqual([w for w in args.split() if not w.startswith(("-", ">", "2>"))], ['"${missing[@]}"'],
                             f"./imca: apt-get install{args}")

    def test_every_package_of_imca_is_installed_here(self):
        # ./imca test installed these: a misspelt or vanished name fails.
        for tag in ("build", "runtime", "host", "test"):
            missing = sorted(tagged(self.packages, tag) - set(self.db))
            self.assertEqual(missing, [], f"tag {tag}: not installed (./imca test installs them)")

    def test_dockerfiles_install_from_the_list_only(self):
        for path, stages in DOCKERFILES.items():
            copied = {}
            installs = {}
            for stage, instruction, text in dockerfile_runs(path):
                if instruction == "COPY" and "packages.txt" in text:
                    source, destination = text.split()[-2:]
                    self.assertTrue(source.endswith("packages.txt"), f"{path}: {text}")
                    copied[stage] = destination
                if instruction == "COPY" and re.match(r"^\.\s", text):
                    self.assertIn(stage, copied, f"{path}: stage {stage} copies the sources before the list "
                                                 "(every source change would reinstall the packages)")
                if instruction != "RUN" or "apt-get install" not in text:
                    continue
                self.assertIn(stage, copied, f"{path}: stage {stage} installs before copying the list")
                self.assertIn("--no-install-recommends", text, path)
                self.assertNotIn(stage, installs, f"{path}: stage {stage} installs twice")
                # The names are the output of one command substitution over
                # the copied list, and nothing else follows `install`.
                sub, rest = substitution(text.split("apt-get install", 1)[1])
                self.assertIn("packages.txt", sub, f"{path}: stage {stage}: {text}")
                self.assertEqual([w for w in rest.split("&&")[0].split() if not w.startswith("-")], [],
                                 f"{path}: stage {stage} names packages itself")
                with tempfile.TemporaryDirectory() as tmp:
                    command = sub.replace(copied[stage], os.path.join(tmp, "packages.txt"))
                    os.symlink(LIST, os.path.join(tmp, "packages.txt"))
                    r = subprocess.run(["sh", "-c", command], capture_output=True, text=True, check=True)
                installs[stage] = r.stdout.split()
            self.assertEqual(set(installs), set(stages), f"{path}: the stages that install")
            for stage, tag in stages.items():
                self.assertEqual(installs[stage], [p for p, t in self.packages.items() if tag in t],
                                 f"{path}: stage {stage} installs other than the list's {tag} packages")

    def test_shipped_binaries_load_only_runtime_packages(self):
        runtime = tagged(self.packages, "runtime")
        pulled = closure(runtime | BASE, self.db)
        for binary in SHIPPED:
            path = os.path.join(BIN, binary)
            self.assertTrue(os.path.exists(path), f"{path}: build first")
            ldd = subprocess.run(["ldd", path], capture_output=True, text=True, check=True).stdout
            self.assertNotIn("not found", ldd, binary)
            loaded = re.findall(r"=> (/\S+)", ldd)
            readelf = subprocess.run(["readelf", "-d", path], capture_output=True, text=True, check=True).stdout
            needed = set(re.findall(r"\(NEEDED\)\s+Shared library: \[(.+?)\]", readelf))
            self.assertTrue(loaded and needed, binary)
            found = owners(loaded)
            for lib in loaded:
                self.assertTrue(found[lib], f"{binary}: {lib} belongs to no package")
                if os.path.basename(lib) in needed or through_alternatives(lib):
                    # Linked directly, or chosen by update-alternatives (as
                    # libblas.so.3: installing its package chooses it, no
                    # dependency does): its package is named in the list.
                    self.assertTrue(found[lib] & (runtime | BASE),
                                    f"{binary} links {lib} of {sorted(found[lib])}: tag it runtime in "
                                    "deploy/packages.txt")
                else:
                    self.assertTrue(found[lib] & pulled,
                                    f"{binary} loads {lib} of {sorted(found[lib])}, which no runtime package "
                                    "pulls in")

    def test_the_base_allowance_is_debians_own(self):
        base = closure({p for p, (_, _, required) in self.db.items() if required}, self.db)
        self.assertEqual(sorted(BASE - base), [], "not part of Debian's essential/required set")
        self.assertEqual(sorted(BASE & set(self.packages)), [], "allowed as base: do not list them")

    def test_cmake_finds_only_build_packages(self):
        build_dir = os.path.dirname(BIN)
        cache_path = os.path.join(build_dir, "CMakeCache.txt")
        self.assertTrue(os.path.exists(cache_path), f"{cache_path}: configure first")
        cache = {}
        with open(cache_path) as f:
            for line in f:
                m = re.match(r"^([^#/][^:]*):(FILEPATH|PATH)=(/.*)$", line.strip())
                if m:
                    cache[m.group(1)] = m.group(3)
        finds, modules = set(), set()
        for top, dirs, files in os.walk(ROOT):
            dirs[:] = [d for d in dirs if not d.startswith(("build", ".", "results", "runs"))]
            if "CMakeLists.txt" in files:
                with open(os.path.join(top, "CMakeLists.txt")) as f:
                    text = f.read()
                finds |= set(re.findall(r"find_package\(\s*([\w-]+)", text))
                for args in re.findall(r"pkg_(?:check|search)_modules\(([^)]*)\)", text):
                    words = [w for w in args.split() if w not in PKG_KEYWORDS]
                    modules |= {re.split(r"[<>=]", w)[0] for w in words[1:]}
        self.assertTrue(finds, "no find_package in CMakeLists.txt?")
        build = tagged(self.packages, "build")
        paths = {}
        for name in sorted(finds - NOT_PACKAGES):
            found = [v for k, v in cache.items() if k.lower().startswith(name.lower() + "_")
                     and v.rstrip("/") not in SHARED_DIRS and os.path.exists(v)]
            self.assertTrue(found, f"find_package({name}): no cache entry to trace its package by")
            paths[f"find_package({name})"] = found
        for module in sorted(modules):
            r = subprocess.run(["pkg-config", "--path", module], capture_output=True, text=True)
            self.assertEqual(r.returncode, 0, f"pkg-config {module}: {r.stderr}")
            paths[f"pkg_check_modules({module})"] = [r.stdout.strip()]
        paths["find_package(PkgConfig)"] = [cache["PKG_CONFIG_EXECUTABLE"]]
        found = owners([p for ps in paths.values() for p in ps])
        for what, ps in paths.items():
            for p in ps:
                self.assertTrue(found[p] & build, f"{what} finds {p} of {sorted(found[p])}: tag it build in "
                                                  "deploy/packages.txt")
        # Whatever else configure found (their config files' dependencies,
        # the compilers) comes with the build packages.
        pulled = closure(build, self.db)
        rest = [v for k, v in cache.items() if not k.startswith("CMAKE_INSTALL") and os.path.isfile(v)
                and v.startswith("/usr/") and not v.startswith("/usr/local/")]
        found = owners(rest)
        for p in rest:
            self.assertTrue(found[p] & pulled, f"configure found {p} of {sorted(found[p])}, which no build "
                                               "package pulls in")


if __name__ == "__main__":
    unittest.main(verbosity=2)
