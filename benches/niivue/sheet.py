"""One side-by-side sheet: N renders in a row, a label strip above each (pillow).
Usage: sheet.py OUT.png IMAGE1.png LABEL1 [IMAGE2.png LABEL2 ...]
Labels wrap to their column's width (the strip grows to the longest label); columns keep their
own sizes, top-aligned. Keeps the sheet under ~400 KB by falling back to a 256-colour palette
when the full-colour PNG is larger."""
import io
import sys

from PIL import Image, ImageDraw

LINE = 12  # pixels per line of pillow's default bitmap font, with spacing


def wrap(draw, text, width):
    """Greedy word wrap of `text` to `width` pixels; a word longer than that stays whole."""
    lines, cur = [], ""
    for word in text.split():
        cand = f"{cur} {word}".strip()
        if cur and draw.textlength(cand) > width:
            lines.append(cur)
            cur = word
        else:
            cur = cand
    return lines + [cur] if cur else lines


def main(argv):
    if len(argv) < 3 or len(argv) % 2 != 1:
        sys.exit("usage: sheet.py OUT.png IMAGE1.png LABEL1 [IMAGE2.png LABEL2 ...]")
    out, pairs = argv[0], list(zip(argv[1::2], argv[2::2]))
    images = [Image.open(path).convert("RGB") for path, _ in pairs]
    probe = ImageDraw.Draw(Image.new("RGB", (1, 1)))
    labels = [wrap(probe, label, im.width - 12) for im, (_, label) in zip(images, pairs)]
    strip = 10 + LINE * max(len(lines) for lines in labels)
    sheet = Image.new("RGB", (sum(im.width for im in images),
                              strip + max(im.height for im in images)), "black")
    draw = ImageDraw.Draw(sheet)
    x = 0
    for im, lines in zip(images, labels):
        sheet.paste(im, (x, strip))
        for i, line in enumerate(lines):
            draw.text((x + 6, 5 + LINE * i), line, fill="white")
        x += im.width
    buf = io.BytesIO()
    sheet.save(buf, "PNG", optimize=True)
    if buf.tell() > 400_000:
        buf = io.BytesIO()
        sheet.quantize(256).save(buf, "PNG", optimize=True)
    open(out, "wb").write(buf.getvalue())
    print(f"{out}: {sheet.width}x{sheet.height}, {buf.tell() // 1024} KB")


if __name__ == "__main__":
    main(sys.argv[1:])
