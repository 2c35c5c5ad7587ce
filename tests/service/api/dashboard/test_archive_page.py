"""The run page's archive heatmap in headless Chromium against a real server: on the tiny
land run it draws one cell per elite of ``GET /runs/{id}/archive`` and leaves the others
blank, labels its axes with the measures and their bounds, and a click on a filled cell
opens that cell's elite (its page and replay). The screenshot goes to docs/archive-heatmap.png."""

from __future__ import annotations

from pathlib import Path

import httpx
import numpy as np
import pytest

from tests.service.api.dashboard.chromium import browser_missing
from tests.service.api.dashboard.test_browser import pixels

pytestmark = pytest.mark.skipif(browser_missing() is not None, reason=str(browser_missing()))

DOCS = Path(__file__).resolve().parents[4] / "docs"
PLOT_MS = 60_000

# the page position of each cell centre of the heatmap, read from plotly's own axes
CELL_CENTRES = """() => {
  const div = document.getElementById("archive"), layout = div._fullLayout, box = div.getBoundingClientRect();
  const trace = div._fullData[0];
  return trace.y.map((y, row) => trace.x.map((x, col) => ({
    row, col, z: trace.z[row][col], individual: trace.customdata[row][col],
    px: box.left + layout.xaxis._offset + layout.xaxis.l2p(x),
    py: box.top + layout.yaxis._offset + layout.yaxis.l2p(y),
  })));
}"""


def test_archive_heatmap_draws_the_elites_and_a_click_opens_one(dashboard_url, tiny_db, open_page):
    archive = httpx.get(f"{dashboard_url}/runs/{tiny_db.run_id}/archive").json()
    assert archive["filled"] >= 1
    page = open_page(dashboard_url).page
    page.goto(f"{dashboard_url}/dashboard/runs/{tiny_db.run_id}")
    page.wait_for_selector("#archive .heatmaplayer image", timeout=PLOT_MS)
    page.wait_for_function(f"document.getElementById('archive').dataset.filled === '{archive['filled']}'")
    summary = page.locator("#archive-summary").inner_text()
    assert f"{archive['filled']} of 36 cells" in summary and "QD score" in summary
    titles = " ".join(page.locator("#archive .g-xtitle, #archive .g-ytitle").all_text_contents())
    assert "frequency (Hz) [0, 5" in titles and "branching index [0, 1" in titles
    page.locator("#archive").scroll_into_view_if_needed()
    cells = [cell for row in page.evaluate(CELL_CENTRES) for cell in row]
    drawn = {(c["col"], c["row"]): (c["individual"], c["z"]) for c in cells if c["z"] is not None}
    assert drawn == {tuple(e["cell"]): (e["individual"], e["distance"]) for e in archive["elites"]}
    assert len(cells) - len(drawn) == 36 - archive["filled"]  # blank cells: no value drawn
    image = pixels(page.locator("#archive").screenshot(path=str(DOCS / "archive-heatmap.png")))
    assert float(np.ptp(image[..., :3], axis=-1).mean()) > 1  # colour, not a blank panel
    target = max(archive["elites"], key=lambda e: e["distance"])
    cell = next(c for c in cells if c["individual"] == target["individual"])
    page.mouse.move(cell["px"], cell["py"])  # plotly takes the click of the point it hovers
    page.mouse.click(cell["px"], cell["py"])
    page.wait_for_url(f"**/dashboard/individuals/{target['individual']}?environment=land")
    page.wait_for_selector("#objectives table")
