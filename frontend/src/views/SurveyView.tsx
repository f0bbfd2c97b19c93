import { MineMap } from "../map/MineMap";

export function SurveyView({ siteId }: { siteId: number }) {
  return <MineMap key={siteId} siteId={siteId} />;
}
