"""One side-by-side sheet: two same-size renders with a label strip above each (pillow).
Usage: sheet.py LEFT.png RIGHT.png OUT.png LEFT_LABEL RIGHT_LABEL. Keeps the sheet under ~400 KB
by falling back to a 256-colour palette when the full-colour PNG is larger."""
import io
import sys

from PIL import Image, ImageDraw

left, right, out, llabel, rlabel = sys.argv[1:6]
a, b = Image.open(left).convert("RGB"), Image.open(right).convert("RGB")
strip = 22
sheet = Image.new("RGB", (a.width + b.width, max(a.height, b.height) + strip), "black")
sheet.paste(a, (0, strip))
sheet.paste(b, (a.width, strip))
draw = ImageDraw.Draw(sheet)
draw.text((6, 5), llabel, fill="white")
draw.text((a.width + 6, 5), rlabel, fill="white")
buf = io.BytesIO()
sheet.save(buf, "PNG", optimize=True)
if buf.tell() > 400_000:
    buf = io.BytesIO()
    sheet.quantize(256).save(buf, "PNG", optimize=True)
open(out, "wb").write(buf.getvalue())
print(f"{out}: {sheet.width}x{sheet.height}, {buf.tell() // 1024} KB")
