"""The offline grader's image (autograder/release/gradescope_bundle/Dockerfile) is Gradescope's: the
same Ubuntu and Python as setup.sh says, the same pinned wheels as requirements.txt (both lists
parsed here), nothing of theirs overridden, and the guide's docker commands build it and run the
guide's own ``batch`` in it. Docker itself is not needed: nothing here builds or runs the image."""

import re
import shlex

from packaging.requirements import Requirement

from course.core.impl import REPO_ROOT

BUNDLE = REPO_ROOT / "autograder" / "release" / "gradescope_bundle"
DOCKERFILE = BUNDLE / "Dockerfile"
GUIDE = REPO_ROOT / "docs" / "teaching.md"
#: the CPython each Ubuntu release installs as python3
UBUNTU_PYTHON = {"20.04": "3.8", "22.04": "3.10", "24.04": "3.12"}
#: what a whole class's run imports beyond grading one submission, and the wheel that gives it
CLASS_IMPORTS = {"tqdm": "tqdm", "yaml": "pyyaml", "matplotlib": "matplotlib"}


def instructions(path=DOCKERFILE) -> list:
    """``(INSTRUCTION, arguments)`` of a Dockerfile, continuation lines joined, comments dropped."""
    text = re.sub(r"\\\n\s*", " ", path.read_text())
    return [tuple(line.strip().split(None, 1)) for line in text.splitlines()
            if line.strip() and not line.lstrip().startswith("#")]


def pins(specs) -> dict:
    """``{name: version}`` of pinned requirement specs (``name==version``, markers allowed)."""
    found = {}
    for spec in specs:
        req = Requirement(spec)
        (version,) = [s.version for s in req.specifier if s.operator == "=="]
        found[req.name.lower()] = version
    return found


def requirement_file(path) -> dict:
    lines = [line.split("  #")[0].strip() for line in path.read_text().splitlines()]
    return pins(line for line in lines if line and not line.startswith("#"))


def pip_installs(command: str) -> list:
    """The requirement specs and ``-r`` files of each ``pip install`` in a shell command."""
    words = shlex.split(command.replace("&&", " && "))
    specs = []
    for start in [i for i in range(len(words) - 1) if words[i:i + 2] == ["pip", "install"]]:
        rest = words[start + 2:]
        rest = rest[:rest.index("&&")] if "&&" in rest else rest
        it = iter(rest)
        for word in it:
            if word == "-r":
                specs.append(("-r", next(it)))
            elif not word.startswith("-"):
                specs.append(("spec", word))
    return specs


def image_packages() -> tuple:
    """``(from setup.sh's requirement files, the Dockerfile's own pins)``, each ``{name: version}``."""
    graded: dict = {}
    own: list = []
    for kind, args in instructions():
        if kind != "RUN":
            continue
        if "setup.sh" in args:
            setup = (BUNDLE / "setup.sh").read_text()
            for what, value in (item for line in setup.splitlines() if "pip install" in line
                                for item in pip_installs(line)):
                assert what == "-r", f"setup.sh installs {value} outside requirements.txt"
                graded.update(requirement_file(BUNDLE / value.removeprefix("$SOURCE/")))
        own += [value for what, value in pip_installs(args) if what == "spec"]
    return graded, pins(own)


def test_the_image_is_gradescope_s_ubuntu_and_python():
    base = dict(instructions())["FROM"]
    assert base.startswith("ubuntu:")
    ubuntu = base.split(":")[1]
    setup = (BUNDLE / "setup.sh").read_text()
    assert f"Ubuntu {ubuntu}" in setup and f"CPython {UBUNTU_PYTHON[ubuntu]}" in setup
    assert f"--python-version {UBUNTU_PYTHON[ubuntu]}" in (BUNDLE / "requirements.txt").read_text()
    apt = next(args for kind, args in instructions() if kind == "RUN" and "apt-get install" in args)
    assert "python3 " in apt + " " and not re.search(r"python3\.\d+", apt)  # the release's own python3
    for kind, args in instructions():  # what it copies is the bundle's own files (the build context)
        if kind == "COPY":
            *sources, _ = args.split()
            assert all((BUNDLE / source).is_file() for source in sources)
    assert "RUN bash /autograder/source/setup.sh" in " ".join(" ".join(i) for i in instructions())


def test_the_image_installs_requirements_txt_and_overrides_none_of_it():
    graded, own = image_packages()
    assert graded == requirement_file(BUNDLE / "requirements.txt")
    assert {"numpy", "scipy", "qdldl", "pyceres", "threadpoolctl", "tomli"} <= set(graded)
    assert not set(own) & set(graded), "the Dockerfile pins again a package of requirements.txt"
    assert set(own) == set(CLASS_IMPORTS.values())
    for name in graded | own:
        assert re.fullmatch(r"[0-9][0-9a-z.]*", (graded | own)[name]), name
    assert all("--only-binary=:all:" in args for kind, args in instructions()
               if kind == "RUN" and "pip install" in args)
    # each extra is imported by a whole class's run, and the pins satisfy the package's own constraints
    classroom = " ".join(p.read_text() for p in (REPO_ROOT / "autograder" / "classroom").glob("*.py"))
    for module in CLASS_IMPORTS:
        assert re.search(rf"^\s*(from|import) {module}\b", classroom, re.M), module
    pyproject = (REPO_ROOT / "pyproject.toml").read_text()
    block = pyproject[pyproject.index("dependencies = ["):pyproject.index("[project.optional-dependencies]")]
    wanted = {Requirement(spec).name.lower(): Requirement(spec) for spec in re.findall(r'^\s*"([^"]+)"', block, re.M)}
    for name, version in (graded | own).items():
        if name in wanted:
            assert wanted[name].specifier.contains(version, prereleases=False), (name, version, wanted[name])


def test_the_guide_builds_the_image_and_runs_its_own_batch_in_it():
    blocks = re.findall(r"```sh\n(.*?)```", GUIDE.read_text(), re.S)
    lines = [shlex.split(line) for block in blocks for line in block.splitlines() if line.startswith("docker ")]
    build = next(words for words in lines if words[1] == "build")
    tag = build[build.index("-t") + 1]
    assert (REPO_ROOT / build[-1]).resolve() == BUNDLE
    runs = [words for words in lines if words[1] == "run"]
    assert runs and all(tag in words for words in runs)
    workdir = dict(instructions())["WORKDIR"]
    bash = re.findall(r"```bash\n(.*?)```", GUIDE.read_text(), re.S)
    guide_commands = [shlex.split(line) for block in bash for line in block.splitlines() if line.strip()]
    grade = next(words for words in runs if "batch" in words)
    assert grade[grade.index("-v") + 1] == f"$PWD:{workdir}"
    assert grade[grade.index(tag) + 1:] in guide_commands  # the guide's own batch, run by its test
