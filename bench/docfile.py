"""Writing the benchmark pages, plots and JSON (bench/report.py, bench/first_call.py,
bench/mitsuba_side_by_side.py, bench/python_calls.py, bench/pocl_pinning.py): every file goes
through a temporary file in its folder and a rename, so a failed run leaves the old file whole;
onto what is not a regular file (a pipe, /dev/null) it is written directly."""
import os
import shutil
import tempfile


def _replace_with(path, write, suffix=""):
    """Calls write(temporary path) and renames the result onto `path`, keeping its mode."""
    if os.path.exists(path) and not os.path.isfile(path):
        write(path)
        return
    if os.path.exists(path):
        mode = os.stat(path).st_mode & 0o777
    else:
        umask = os.umask(0)
        os.umask(umask)
        mode = 0o666 & ~umask
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(os.path.abspath(path)),
                               prefix="." + os.path.basename(path) + ".", suffix=suffix)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def write_text(path, text):
    def write(p):
        with open(p, "w") as f:
            f.write(text)
    _replace_with(path, write)


def save_figure(fig, path, **kwargs):
    """fig.savefig to `path`; the temporary file keeps the extension, which picks the format."""
    _replace_with(path, lambda p: fig.savefig(p, **kwargs), os.path.splitext(path)[1])


def copy_file(src, path):
    _replace_with(path, lambda p: shutil.copyfile(src, p), os.path.splitext(path)[1])


def _section_bounds(text, title):
    """[start, end) of the section of `text` (a list of lines) titled `title`, up to the next
    "## "; None where there is none."""
    if title not in text:
        return None
    start = text.index(title)
    end = next((i for i in range(start + 1, len(text)) if text[i].startswith("## ")), len(text))
    return start, end


def section_lines(path, title):
    """The lines of the page's section titled `title`, [] where the page has none."""
    if not os.path.isfile(path):
        return []
    text = open(path).read().split("\n")
    bounds = _section_bounds(text, title)
    return text[bounds[0]:bounds[1]] if bounds else []


def replace_section(path, lines, before=None):
    """Replaces the section of the page titled lines[0] (up to the next "## ") with `lines`;
    a page without it gets it before the line `before`, else at the end."""
    text = open(path).read().split("\n")
    bounds = _section_bounds(text, lines[0])
    if bounds is None:
        at = text.index(before) if before in text else len(text)
        bounds = (at, at)
    write_text(path, "\n".join(text[:bounds[0]] + lines + text[bounds[1]:]))
