import { useCallback, useEffect, useState } from "react";
import { apiGet, setUnauthorizedHandler, type Schemas } from "./api/client";
import { canEdit, forget, isAdmin, logout, restore, type Me } from "./session";
import { LoginPage } from "./views/LoginPage";
import { SurveyView } from "./views/SurveyView";
import { MonitorView } from "./views/MonitorView";
import { GroundingView } from "./views/GroundingView";
import { AdminView } from "./views/AdminView";
import { CamerasView } from "./views/cameras/CamerasView";

type Page = "survey" | "monitor" | "grounding" | "cameras" | "admin";
const PAGES: { id: Page; label: string; show: (me: Me) => boolean }[] = [
  { id: "survey", label: "Survey map", show: () => true },
  { id: "monitor", label: "Monitoring", show: () => true },
  { id: "grounding", label: "Grounding", show: () => true },
  { id: "cameras", label: "Cameras", show: canEdit },
  { id: "admin", label: "Admin", show: isAdmin },
];

export function App() {
  const [me, setMe] = useState<Me | null>(null);
  const [checked, setChecked] = useState(false);
  const [page, setPage] = useState<Page>(() => (location.hash.slice(1) as Page) || "survey");
  const [sites, setSites] = useState<Schemas["SiteRead"][]>([]);
  const [siteId, setSiteId] = useState<number | null>(null);
  // below 900 px (a tablet): the header's contents fold into a menu, the side panel into a pull-up panel
  const [menuOpen, setMenuOpen] = useState(false);
  const [panelOpen, setPanelOpen] = useState(false);

  useEffect(() => {
    setUnauthorizedHandler(() => {
      forget();
      setMe(null);
    });
    void restore().then((m) => {
      setMe(m);
      setChecked(true);
    });
  }, []);

  const loadSites = useCallback(async () => {
    const page = await apiGet("/api/sites", {}, { limit: 500 });
    setSites(page.items);
    setSiteId((current) =>
      current !== null && page.items.some((s) => s.id === current) ? current : (page.items[0]?.id ?? null),
    );
  }, []);

  useEffect(() => {
    // loadSites sets state only after its request resolves
    // eslint-disable-next-line react-hooks/set-state-in-effect
    if (me) void loadSites();
  }, [me, loadSites]);

  useEffect(() => {
    location.hash = page;
  }, [page]);

  if (!checked) return null;
  if (!me) return <LoginPage onLogin={setMe} />;
  const visiblePages = PAGES.filter((p) => p.show(me));
  const current = visiblePages.some((p) => p.id === page) ? page : "survey";

  return (
    <div className="shell">
      <header className={`topbar ${menuOpen ? "menu-open" : ""}`}>
        <span className="brand">driftmap</span>
        <span className="spacer narrow-only" />
        <button
          className="menu-button"
          data-testid="menu-toggle"
          aria-expanded={menuOpen}
          aria-label="Menu"
          onClick={() => setMenuOpen((o) => !o)}
        >
          ☰
        </button>
        <div className="menu" data-testid="menu">
          <nav className="nav">
            {visiblePages.map((p) => (
              <button
                key={p.id}
                data-testid={`nav-${p.id}`}
                className={current === p.id ? "active" : ""}
                onClick={() => {
                  setPage(p.id);
                  setMenuOpen(false);
                }}
              >
                {p.label}
              </button>
            ))}
          </nav>
          <span className="spacer" />
          <label className="muted">
            Site{" "}
            <select data-testid="site-select" value={siteId ?? ""} onChange={(e) => setSiteId(Number(e.target.value))}>
              {sites.map((s) => (
                <option key={s.id} value={s.id}>
                  {s.name}
                </option>
              ))}
            </select>
          </label>
          <span data-testid="whoami">
            {me.name} <span className="muted">({me.role})</span>
          </span>
          <button data-testid="logout" onClick={() => void logout().then(() => setMe(null))}>
            Log out
          </button>
        </div>
      </header>
      <main className={`content ${panelOpen ? "panel-open" : ""}`}>
        <button
          className="panel-handle"
          data-testid="panel-handle"
          aria-expanded={panelOpen}
          onClick={() => setPanelOpen((o) => !o)}
        >
          {panelOpen ? "▼ Map" : "▲ Panel"}
        </button>
        {current === "admin" ? (
          <AdminView sites={sites} onSitesChanged={loadSites} meId={me.id} />
        ) : current === "cameras" ? (
          <CamerasView />
        ) : siteId === null ? (
          <p className="muted" style={{ margin: 24 }}>
            No site yet.{isAdmin(me) ? " Create one under Admin." : ""}
          </p>
        ) : current === "survey" ? (
          <SurveyView siteId={siteId} />
        ) : current === "monitor" ? (
          <MonitorView siteId={siteId} editable={canEdit(me)} />
        ) : (
          <GroundingView siteId={siteId} editable={canEdit(me)} />
        )}
      </main>
    </div>
  );
}
